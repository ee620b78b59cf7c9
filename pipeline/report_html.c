/* report_html: text buffer, escaping and base64 of the run report (see report_html.h). */
#include "pipeline/report_html.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int reserve(rs_html *h, size_t extra)
{
    if (h->failed) return -1;
    if (h->len + extra + 1 <= h->cap) return 0;
    size_t cap = h->cap ? h->cap : 65536;
    while (cap < h->len + extra + 1) cap *= 2;
    char *s = realloc(h->s, cap);
    if (!s) {
        h->failed = 1;
        return -1;
    }
    h->s = s;
    h->cap = cap;
    return 0;
}

void rs_html_printf(rs_html *h, const char *fmt, ...)
{
    va_list ap;
    va_start(ap, fmt);
    char small[512];
    int n = vsnprintf(small, sizeof small, fmt, ap);
    va_end(ap);
    if (n < 0 || reserve(h, (size_t)n) != 0) return;
    if ((size_t)n < sizeof small) {
        memcpy(h->s + h->len, small, (size_t)n + 1);
    } else {
        va_start(ap, fmt);
        vsnprintf(h->s + h->len, (size_t)n + 1, fmt, ap);
        va_end(ap);
    }
    h->len += (size_t)n;
}

void rs_html_put(rs_html *h, const char *text)
{
    size_t n = strlen(text);
    if (reserve(h, n) != 0) return;
    memcpy(h->s + h->len, text, n + 1);
    h->len += n;
}

void rs_html_esc(rs_html *h, const char *text)
{
    for (const char *p = text ? text : ""; *p; p++) {
        switch (*p) {
        case '&': rs_html_put(h, "&amp;"); break;
        case '<': rs_html_put(h, "&lt;"); break;
        case '>': rs_html_put(h, "&gt;"); break;
        case '"': rs_html_put(h, "&quot;"); break;
        default:
            if (reserve(h, 1) == 0) {
                h->s[h->len++] = *p;
                h->s[h->len] = 0;
            }
        }
    }
}

void rs_html_base64(rs_html *h, const unsigned char *d, size_t n)
{
    static const char tab[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    if (reserve(h, (n + 2) / 3 * 4) != 0) return;
    char *o = h->s + h->len;
    size_t k = 0;
    for (; k + 2 < n; k += 3) {
        unsigned v = (unsigned)d[k] << 16 | (unsigned)d[k + 1] << 8 | d[k + 2];
        *o++ = tab[v >> 18];
        *o++ = tab[(v >> 12) & 63];
        *o++ = tab[(v >> 6) & 63];
        *o++ = tab[v & 63];
    }
    if (k < n) {
        unsigned v = (unsigned)d[k] << 16 | (k + 1 < n ? (unsigned)d[k + 1] << 8 : 0);
        *o++ = tab[v >> 18];
        *o++ = tab[(v >> 12) & 63];
        *o++ = k + 1 < n ? tab[(v >> 6) & 63] : '=';
        *o++ = '=';
    }
    *o = 0;
    h->len = (size_t)(o - h->s);
}

void rs_html_release(rs_html *h)
{
    free(h->s);
    memset(h, 0, sizeof *h);
}

/* response: response-curve files (see response.h). A curve measured once (in the lab, or
 * calibrated from a well-exposed scene) is more trustworthy than one fitted to every capture. */
#include "calib/response.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/fileio.h"

int rs_response_read(const char *path, float *out, rs_err *err)
{
    char *text = NULL;
    size_t size = 0;
    if (rs_read_file(path, &text, &size, err) != 0) return -1;
    int rc = rs_response_parse(text, size, path, out, err);
    free(text);
    return rc;
}

int rs_response_parse(const char *data, size_t size, const char *path, float *out, rs_err *err)
{
    if (memchr(data, 0, size))
        return rs_err_set(err, RS_ERR_INPUT, path, 0, "contains a NUL byte: expected a text file of 256 lines");
    char *text = malloc(size + 1);
    if (!text) return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    memcpy(text, data, size);
    text[size] = 0;
    int code = 0, rc = -1;
    long line = 0;
    for (char *p = text; *p;) {
        char *eol = strchr(p, '\n');
        if (eol) *eol = 0;
        line++;
        char *s = p;
        p = eol ? eol + 1 : p + strlen(p);
        while (*s == ' ' || *s == '\t' || *s == '\r') s++;
        if (!*s || *s == '#') continue;
        double v[4];
        int n = 0;
        for (char *q = s; *q;) {
            while (*q == ' ' || *q == '\t' || *q == ',' || *q == '\r') q++;
            if (!*q) break;
            char *end;
            double x = strtod(q, &end);
            /* A number ends at a separator: "1.5x" is not a number followed by a comment. */
            if (end == q || n == 4 || (*end && !strchr(" \t,\r", *end)) || !isfinite(x)) {
                rs_err_set(err, RS_ERR_INPUT, path, line,
                           "\"%.80s\": expected 1 or 3 finite numbers (linear exposure of "
                           "code %d for all channels, or for R G B)",
                           s, code);
                goto out;
            }
            v[n++] = x;
            q = end;
        }
        if (n != 1 && n != 3) {
            rs_err_set(err, RS_ERR_INPUT, path, line,
                       "\"%.80s\" has %d numbers: expected 1 (all channels) or 3 (R G B)", s, n);
            goto out;
        }
        if (code == 256) {
            rs_err_set(err, RS_ERR_INPUT, path, line, "a 257th value: expected 256 lines, one per 8-bit code");
            goto out;
        }
        for (int ch = 0; ch < 3; ch++) {
            double x = v[n == 1 ? 0 : ch];
            /* In float (what the merge takes) and > 0 there: the merge takes its logarithm. */
            if (!(x >= RS_RESPONSE_MIN && x <= RS_RESPONSE_MAX)) {
                rs_err_set(err, RS_ERR_INPUT, path, line,
                           "code %d: %g: expected a linear exposure from %g to %g (the merge "
                           "takes its logarithm)",
                           code, x, RS_RESPONSE_MIN, RS_RESPONSE_MAX);
                goto out;
            }
            if (code > 0 && x < out[3 * (code - 1) + ch]) {
                rs_err_set(err, RS_ERR_INPUT, path, line,
                           "code %d, channel %d: %g is below code %d's %g: expected a "
                           "response that does not decrease",
                           code, ch, x, code - 1, out[3 * (code - 1) + ch]);
                goto out;
            }
            out[3 * code + ch] = (float)x;
        }
        code++;
    }
    if (code != 256) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "%d values: expected 256, one per 8-bit code", code);
        goto out;
    }
    rc = 0;
out:
    free(text);
    return rc;
}

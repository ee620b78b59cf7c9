/* laswrite: a minimal LAS writer for the tests (any version 1.0-1.4, point formats 0-10, extra
 * bytes, padding before the points), so that every field the reader decodes has a known value.
 * Header layout: LAS 1.4 R15, table 3. */
#ifndef RS_TEST_LASWRITE_H
#define RS_TEST_LASWRITE_H

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct las_spec {
    int minor;      /* 0..4: header of 227 (1.0-1.2), 235 (1.3) or 375 (1.4) bytes */
    int format;     /* 0..10 */
    unsigned extra; /* extra bytes per record (after the format's fields) */
    unsigned pad;   /* bytes between the header and the first point */
    double scale[3], offset[3];
    int legacy_zero;         /* 1.4: leave the 32-bit count 0 (only the 64-bit one) */
    uint64_t count_over;     /* when non-zero: the count written in the header instead of n */
    const uint8_t *withheld; /* n flags, or NULL: the withheld bit of each record */
} las_spec;

static const unsigned las_min_record[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
static const unsigned las_rgb_at[11] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};

static inline void las_put16(unsigned char *p, unsigned v)
{
    p[0] = (unsigned char)v, p[1] = (unsigned char)(v >> 8);
}
static inline void las_put32(unsigned char *p, uint32_t v)
{
    for (int i = 0; i < 4; i++) p[i] = (unsigned char)(v >> (8 * i));
}
static inline void las_put64(unsigned char *p, uint64_t v)
{
    for (int i = 0; i < 8; i++) p[i] = (unsigned char)(v >> (8 * i));
}
static inline void las_putd(unsigned char *p, double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    las_put64(p, u);
}

/* The header of s for n points (bbox lo..hi) into h (375 bytes); returns its size. */
static inline unsigned las_header(const las_spec *s, uint64_t n, const double lo[3], const double hi[3],
                                  unsigned char h[375])
{
    unsigned size = s->minor >= 4 ? 375 : s->minor == 3 ? 235 : 227;
    unsigned rec = las_min_record[s->format] + s->extra;
    memset(h, 0, 375);
    memcpy(h, "LASF", 4);
    h[24] = 1, h[25] = (unsigned char)s->minor;
    memcpy(h + 26, "rhoscan tests", 13);
    las_put16(h + 94, size);
    las_put32(h + 96, size + s->pad);
    h[104] = (unsigned char)s->format;
    las_put16(h + 105, rec);
    uint64_t count = s->count_over ? s->count_over : n;
    las_put32(h + 107, s->legacy_zero || count > 0xffffffffu ? 0 : (uint32_t)count);
    for (int j = 0; j < 3; j++) {
        las_putd(h + 131 + 8 * j, s->scale[j]);
        las_putd(h + 155 + 8 * j, s->offset[j]);
        las_putd(h + 179 + 16 * j, hi[j]);
        las_putd(h + 187 + 16 * j, lo[j]);
    }
    if (s->minor >= 4) las_put64(h + 247, count);
    return size;
}

/* One record of format s->format: integer coordinates of xyz, the other fields given. */
static inline void las_record(const las_spec *s, const double *xyz, unsigned intensity, const uint16_t *rgb,
                              unsigned cls, unsigned char *p)
{
    memset(p, 0, las_min_record[s->format] + s->extra);
    for (int j = 0; j < 3; j++) las_put32(p + 4 * j, (uint32_t)(int32_t)llround((xyz[j] - s->offset[j]) / s->scale[j]));
    las_put16(p + 12, intensity);
    if (s->format >= 6)
        p[14] = 0x11, p[16] = (unsigned char)cls;
    else
        p[14] = 0x09, p[15] = (unsigned char)(cls | 0x20); /* a flag bit above the class: must be masked */
    unsigned at = las_rgb_at[s->format];
    if (at && rgb)
        for (int j = 0; j < 3; j++) las_put16(p + at + 2 * j, rgb[j]);
    for (unsigned k = 0; k < s->extra; k++) p[las_min_record[s->format] + k] = 0xa5;
}

/* Writes n points (xyz: 3 n; intensity, cls: n; rgb: 3 n or NULL) to path; 0 or -1. */
static inline int las_write(const char *path, const las_spec *s, size_t n, const double *xyz, const uint16_t *intensity,
                            const uint16_t *rgb, const uint8_t *cls)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < n; i++)
        for (int j = 0; j < 3; j++) lo[j] = fmin(lo[j], xyz[3 * i + j]), hi[j] = fmax(hi[j], xyz[3 * i + j]);
    if (n == 0)
        for (int j = 0; j < 3; j++) lo[j] = hi[j] = 0;
    unsigned char h[375], rec[256];
    unsigned size = las_header(s, n, lo, hi, h);
    FILE *f = fopen(path, "wb");
    if (!f) return -1;
    int ok = fwrite(h, 1, size, f) == size;
    for (unsigned k = 0; k < s->pad; k++) ok &= fputc(0, f) != EOF;
    unsigned len = las_min_record[s->format] + s->extra;
    for (size_t i = 0; i < n && ok; i++) {
        las_record(s, xyz + 3 * i, intensity ? intensity[i] : 0, rgb ? rgb + 3 * i : NULL, cls ? cls[i] : 0, rec);
        if (s->withheld && s->withheld[i]) rec[15] |= s->format >= 6 ? 0x04 : 0x80;
        ok = fwrite(rec, 1, len, f) == len;
    }
    return fclose(f) == 0 && ok ? 0 : -1;
}

#endif

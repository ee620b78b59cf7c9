/* image_stb: the image formats read and written through stb (see image_stb.h): Radiance .hdr,
 * PNG and JPEG reading, PNG previews. Also guards against the faults of Debian's stb_image
 * 2.27 that fuzzing found, before any stb call sees the data. */
#include "common/image_stb.h"

#include <limits.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <zlib.h>
#include "common/fileio.h"

/* stb: the implementations live in this one file; only the formats we detect are compiled. */
#define STBI_ONLY_PNG
#define STBI_ONLY_JPEG
#define STBI_ONLY_HDR
#define STBI_MAX_DIMENSIONS RS_IMAGE_MAX_SIDE
#define STB_IMAGE_IMPLEMENTATION
#define STB_IMAGE_WRITE_IMPLEMENTATION
/* stb's own deflate took a fifth of the render stage at 2048 x 1024 (perf); zlib's fastest level
 * compresses these previews about as well, several times faster. */
static unsigned char *png_deflate(unsigned char *data, int len, int *out_len, int quality);
#define STBIW_ZLIB_COMPRESS png_deflate
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wsign-compare"
#pragma GCC diagnostic ignored "-Wunused-function"
#pragma GCC diagnostic ignored "-Wunused-but-set-variable"
#pragma GCC diagnostic ignored "-Wmissing-field-initializers"
#pragma GCC diagnostic ignored "-Wimplicit-fallthrough"
#include <stb_image.h>
#include <stb_image_write.h>
#pragma GCC diagnostic pop

/* stb takes int sizes. */
static int stb_size_ok(size_t size, const char *name, rs_err *err)
{
    if (size <= (size_t)INT_MAX) return 1;
    rs_err_set(err, RS_ERR_INPUT, name, 0, "file of %zu bytes: too large for a non-EXR image", size);
    return 0;
}

/* Reads one header token exactly as stbi__hdr_gettoken does (up to and including '\n', long
 * lines cut at 1023 bytes, the byte read at the end of the data dropped) and returns 1 when
 * stb sees it as empty: the header ends at the first such token, which may be a line that
 * starts with a NUL byte or the end of the data, not only an empty line. */
static int hdr_token_empty(const unsigned char *p, size_t n, size_t *pos)
{
    size_t len = 0;
    unsigned char first = 0, c = *pos < n ? p[(*pos)++] : 0;
    while (*pos < n && c != '\n') {
        if (len++ == 0) first = c;
        if (len == 1023) {
            while (*pos < n && p[(*pos)++] != '\n') {}
            break;
        }
        c = p[(*pos)++];
    }
    return len == 0 || first == 0;
}

/* Debian's stb_image 2.27 loops forever on a run-length count of 0, which is also what it
 * reads past the end of a truncated file (CVE-2021-42715, fixed upstream after 2.27). This
 * walks the scanlines the way stbi__hdr_load does and returns the offset of the first zero
 * count, or 0 when the data is safe to hand to stb (stb reports any other corruption). */
static size_t hdr_zero_run_at(const unsigned char *p, size_t n, int width, int height)
{
    /* The header as stb parses it: the magic token, tokens up to an empty one, then the
     * resolution line (fuzzing found a header ended by a NUL line that an earlier,
     * line-based version of this walk missed, so stb hung). */
    size_t pos = 0;
    hdr_token_empty(p, n, &pos);
    while (pos < n && !hdr_token_empty(p, n, &pos)) {}
    hdr_token_empty(p, n, &pos);
    /* stb reads flat RGBE without runs when the width rules runs out, or from a row that
     * does not start like a run-length row: it then reads all pixels, 4 bytes each, and
     * pads a short file with zeros. Refuse that instead. */
    size_t pixels = (size_t)width * (size_t)height;
    if (width < 8 || width >= 32768) return pos <= n && (n - pos) / 4 >= pixels ? 0 : n;
#define NEXT() (pos < n ? p[pos++] : (pos++, 0))
    for (int j = 0; j < height; j++) {
        size_t row = pos;
        int c1 = NEXT(), c2 = NEXT(), len = NEXT();
        if (c1 != 2 || c2 != 2 || (len & 0x80))
            return row <= n && (n - row) / 4 >= pixels ? 0 : n; /* flat from here on */
        len = (len << 8) | NEXT();
        if (len != width) return 0;
        for (int k = 0; k < 4; k++) {
            for (int i = 0; i < width;) {
                size_t at = pos;
                int count = NEXT();
                if (count == 0) return at ? at : 1;
                if (count > 128) {
                    count -= 128;
                    pos++;
                } else {
                    pos += (size_t)count;
                }
                if (count > width - i) return 0;
                i += count;
            }
        }
    }
#undef NEXT
    return 0;
}

rs_image *rs_image_hdr_read_mem(const void *data, size_t size, const char *name, rs_err *err)
{
    if (!stb_size_ok(size, name, err)) return NULL;
    int w = 0, h = 0, comp = 0;
    if (!stbi_info_from_memory(data, (int)size, &w, &h, &comp)) {
        rs_err_set(err, RS_ERR_INPUT, name, 0, "Radiance .hdr: %s", stbi_failure_reason());
        return NULL;
    }
    if (rs_image_check_size(w, h, name, err) != 0) return NULL;
    size_t bad = hdr_zero_run_at(data, size, w, h);
    if (bad) {
        rs_err_set(err, RS_ERR_INPUT, name, 0,
                   "Radiance .hdr: run-length data %s at byte %zu: "
                   "expected %d x %d pixels",
                   bad >= size ? "truncated" : "corrupt", bad, w, h);
        return NULL;
    }
    float *px = stbi_loadf_from_memory(data, (int)size, &w, &h, &comp, 3);
    if (!px) {
        rs_err_set(err, RS_ERR_INPUT, name, 0, "Radiance .hdr: %s", stbi_failure_reason());
        return NULL;
    }
    rs_image *img = rs_image_new_or_fail(w, h, 3, name, err);
    if (img) memcpy(img->data, px, sizeof(float) * 3 * (size_t)w * (size_t)h);
    stbi_image_free(px);
    return img;
}

/* ---------------------------------------------------------------- PNG and JPEG */

static unsigned be16(const unsigned char *p)
{
    return (unsigned)p[0] << 8 | p[1];
}
static size_t be32(const unsigned char *p)
{
    return (size_t)be16(p) << 16 | be16(p + 2);
}

/* stb_image 2.27 builds JPEG Huffman tables without checking that a table has at most 256
 * codes, and writes past its arrays when one claims more (fixed upstream after 2.27). This
 * walks the markers as stb does (segments by their length, entropy-coded data up to the next
 * marker) and returns the offset of a Define Huffman Table segment with such a table, else 0. */
static size_t jpeg_bad_huffman_at(const unsigned char *p, size_t n)
{
    size_t pos = 2; /* after SOI */
    while (pos + 1 < n) {
        if (p[pos] != 0xff || p[pos + 1] == 0x00 || (p[pos + 1] >= 0xd0 && p[pos + 1] <= 0xd7)) {
            pos++; /* entropy-coded data (0xff 0x00 is a stuffed byte) or restart markers */
            continue;
        }
        unsigned marker = p[pos + 1];
        if (marker == 0xff || marker == 0x01) {
            pos++;
            continue;
        }
        if (marker == 0xd9 || pos + 4 > n) break; /* EOI, or no room for a length */
        size_t len = be16(p + pos + 2), seg = pos + 4, end = pos + 2 + len;
        if (marker == 0xc4) {
            for (size_t q = seg; q < end && q < n;) {
                size_t codes = 0;
                for (size_t i = 1; i <= 16; i++) codes += q + i < n ? p[q + i] : 0;
                if (codes > 256) return pos;
                q += 17 + codes;
            }
        }
        pos = end > pos ? end : pos + 2;
    }
    return 0;
}

/* stb_image 2.27 does arithmetic on a NULL buffer when the first IDAT chunk of a PNG is empty
 * (undefined behaviour that sanitizers stop on). Such files are legal but unheard of: refuse
 * them. Returns 1 when the first IDAT is empty. */
static int png_first_idat_empty(const unsigned char *p, size_t n)
{
    for (size_t pos = 8; pos + 8 <= n;) {
        size_t len = be32(p + pos);
        if (memcmp(p + pos + 4, "IDAT", 4) == 0) return len == 0;
        if (len > n - pos - 8) break;
        pos += 12 + len;
    }
    return 0;
}

/* The checks before stb decodes a PNG or JPEG; its size into *w, *h. */
static int ldr_check(const void *data, size_t size, const char *name, const char *kind, int *wp, int *hp, rs_err *err)
{
    int w = 0, h = 0, comp = 0;
    /* Before any stb call: stbi_info already builds the Huffman tables. */
    size_t bad_dht = kind[0] == 'J' ? jpeg_bad_huffman_at(data, size) : 0;
    if (bad_dht) {
        rs_err_set(err, RS_ERR_INPUT, name, 0,
                   "JPEG: Huffman table at byte %zu has more than "
                   "256 codes: expected a valid JPEG",
                   bad_dht);
        return -1;
    }
    if (kind[0] == 'P' && png_first_idat_empty(data, size)) {
        rs_err_set(err, RS_ERR_INPUT, name, 0, "PNG: empty first IDAT chunk: not supported");
        return -1;
    }
    if (!stbi_info_from_memory(data, (int)size, &w, &h, &comp)) {
        rs_err_set(err, RS_ERR_INPUT, name, 0, "%s: %s", kind, stbi_failure_reason());
        return -1;
    }
    if (rs_image_check_size(w, h, name, err) != 0) return -1;
    /* stb decodes a truncated JPEG to its full size without complaint, so a few hundred bytes
     * can ask for millions of pixels. Real JPEGs hold at most a few hundred pixels per byte
     * (a flat 8 x 8 block still costs bits), so 4096 only refuses impossible ones. */
    if (kind[0] == 'J' && (long long)w * h > 4096LL * (long long)size) {
        rs_err_set(err, RS_ERR_INPUT, name, 0,
                   "JPEG: %d x %d pixels cannot come from %zu bytes: "
                   "truncated or corrupt",
                   w, h, size);
        return -1;
    }
    *wp = w;
    *hp = h;
    return 0;
}

/* 8- or 16-bit PNG and JPEG: sRGB-decoded to linear; grey (+alpha) -> 1 channel, colour
 * (+alpha) -> 3; alpha is dropped. */
static rs_image *ldr_read_mem(const void *data, size_t size, const char *name, const char *kind, rs_err *err)
{
    int w = 0, h = 0, comp = 0;
    if (ldr_check(data, size, name, kind, &w, &h, err) != 0) return NULL;
    int is16 = stbi_is_16_bit_from_memory(data, (int)size);
    void *px = is16 ? (void *)stbi_load_16_from_memory(data, (int)size, &w, &h, &comp, 0)
                    : (void *)stbi_load_from_memory(data, (int)size, &w, &h, &comp, 0);
    if (!px) {
        rs_err_set(err, RS_ERR_INPUT, name, 0, "%s: %s", kind, stbi_failure_reason());
        return NULL;
    }
    int out_c = comp >= 3 ? 3 : 1;
    rs_image *img = rs_image_new_or_fail(w, h, out_c, name, err);
    if (img) {
        float lut[256];
        for (int i = 0; i < 256; i++) lut[i] = rs_srgb_to_linear((float)i / 255.0f);
        size_t n = (size_t)w * (size_t)h;
        for (size_t i = 0; i < n; i++)
            for (int k = 0; k < out_c; k++) {
                size_t s = i * (size_t)comp + (size_t)k;
                img->data[i * (size_t)out_c + (size_t)k] = is16
                    ? rs_srgb_to_linear((float)((const uint16_t *)px)[s] / 65535.0f)
                    : lut[((const unsigned char *)px)[s]];
            }
    }
    stbi_image_free(px);
    return img;
}

/* stb_image 2.27 grows its IDAT buffer to a chunk's declared length before it reads the
 * chunk, so a 100-byte PNG that claims a 1 GB chunk makes it allocate 1 GB (found by
 * fuzzing). Returns the offset of the first chunk whose length runs past the data, else 0. */
static size_t png_chunk_past_end_at(const unsigned char *p, size_t n)
{
    for (size_t pos = 8; pos + 8 <= n;) {
        size_t len = (size_t)p[pos] << 24 | (size_t)p[pos + 1] << 16 | (size_t)p[pos + 2] << 8 | p[pos + 3];
        if (len > n - pos - 8 || n - pos - 8 - len < 4) return pos; /* data and CRC must fit */
        if (memcmp(p + pos + 4, "IEND", 4) == 0) break;
        pos += 12 + len;
    }
    return 0;
}
rs_image *rs_image_png_read_mem(const void *data, size_t size, const char *name, rs_err *err)
{
    if (!stb_size_ok(size, name, err)) return NULL;
    size_t cut = png_chunk_past_end_at(data, size);
    if (cut) {
        rs_err_set(err, RS_ERR_INPUT, name, 0,
                   "PNG: chunk at byte %zu runs past the end of "
                   "the %zu-byte file: truncated or corrupt",
                   cut, size);
        return NULL;
    }
    return ldr_read_mem(data, size, name, "PNG", err);
}

rs_image *rs_image_jpeg_read_mem(const void *data, size_t size, const char *name, rs_err *err)
{
    if (!stb_size_ok(size, name, err)) return NULL;
    return ldr_read_mem(data, size, name, "JPEG", err);
}

/* ---------------------------------------------------------------- PNG previews */

typedef struct byte_buf {
    unsigned char *p;
    size_t n, cap;
    int failed;
} byte_buf;

static void byte_buf_append(void *ctx, void *data, int size)
{
    byte_buf *b = ctx;
    if (b->failed || size <= 0) return;
    if (b->n + (size_t)size > b->cap) {
        size_t cap = b->cap ? b->cap : 65536;
        while (cap < b->n + (size_t)size) cap *= 2;
        unsigned char *p = realloc(b->p, cap);
        if (!p) {
            b->failed = 1;
            return;
        }
        b->p = p;
        b->cap = cap;
    }
    memcpy(b->p + b->n, data, (size_t)size);
    b->n += (size_t)size;
}

static unsigned char *png_deflate(unsigned char *data, int len, int *out_len, int quality)
{
    (void)quality;
    uLongf n = compressBound((uLong)len);
    unsigned char *out = malloc(n);
    if (!out || compress2(out, &n, data, (uLong)len, Z_BEST_SPEED) != Z_OK || n > INT_MAX) {
        free(out);
        return NULL;
    }
    *out_len = (int)n;
    return out;
}

/* 8-bit sRGB codes of linear values in [0, 1], rounded as (int)(rs_linear_to_srgb(v) * 255 + 0.5)
 * without a powf per channel: thr[c - 1] is the smallest float whose code is c, and base[b] the
 * code at b / SRGB_BUCKETS. A bucket is narrower than the narrowest code (3e-4 near black), so at
 * most one threshold lies in it and one comparison either way settles the code. */
enum { SRGB_BUCKETS = 8192 };
typedef struct {
    float thr[255];
    unsigned char base[SRGB_BUCKETS + 1];
} srgb_table;

static int srgb_slow(float v)
{
    return (int)(rs_linear_to_srgb(v) * 255.0f + 0.5f);
}

static void srgb_table_init(srgb_table *t)
{
    for (int c = 1; c < 256; c++) {
        /* Start at the inverse curve, then step float by float to the first value with code c. */
        float x = rs_srgb_to_linear((c - 0.5f) / 255.0f);
        while (x > 0 && srgb_slow(nextafterf(x, 0)) >= c) x = nextafterf(x, 0);
        while (srgb_slow(x) < c) x = nextafterf(x, 2);
        t->thr[c - 1] = x;
    }
    int code = 0;
    for (int b = 0; b <= SRGB_BUCKETS; b++) {
        float v = (float)b / SRGB_BUCKETS;
        while (code < 255 && t->thr[code] <= v) code++;
        t->base[b] = (unsigned char)code;
    }
}

static unsigned char srgb_code(const srgb_table *t, float v)
{
    int code = t->base[(int)(v * SRGB_BUCKETS)];
    if (code > 0 && v < t->thr[code - 1])
        code--;
    else if (code < 255 && v >= t->thr[code])
        code++;
    return (unsigned char)code;
}

static int write_png8(const unsigned char *px, int width, int height, int channels, int filter, const char *path,
                      rs_err *err);

int rs_image_write_png(const rs_image *img, const char *path, float scale, rs_err *err)
{
    if (!img || !img->data || (img->channels != 1 && img->channels != 3))
        return rs_err_set(err, RS_ERR_INTERNAL, path, 0, "rs_image_write_png: %d channels: expected 1 or 3",
                          img ? img->channels : 0);
    if (rs_image_check_size(img->width, img->height, path, err) != 0) return -1;
    size_t n = (size_t)img->width * (size_t)img->height * (size_t)img->channels;
    unsigned char *px = malloc(n);
    if (!px) return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    srgb_table *tab = malloc(sizeof *tab);
    if (!tab) {
        free(px);
        return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    }
    srgb_table_init(tab);
#pragma omp parallel for schedule(static) if (n > 65536)
    for (size_t i = 0; i < n; i++) {
        float v = scale * img->data[i];
        v = v > 0.0f ? (v < 1.0f ? v : 1.0f) : 0.0f; /* also maps NaN to 0 */
        px[i] = srgb_code(tab, v);
    }
    free(tab);
    int status = write_png8(px, img->width, img->height, img->channels, -1, path, err);
    free(px);
    return status;
}

/* filter: stb's PNG row filter, -1 for its choice per row (trying all five). */
static int write_png8(const unsigned char *px, int width, int height, int channels, int filter, const char *path,
                      rs_err *err)
{
    if (channels != 1 && channels != 3)
        return rs_err_set(err, RS_ERR_INTERNAL, path, 0, "rs_image_write_png8: %d channels: expected 1 or 3", channels);
    if (rs_image_check_size(width, height, path, err) != 0) return -1;
    byte_buf b = {0};
    int ok;
#pragma omp critical(rs_png_filter) /* stb keeps the filter in a global */
    {
        stbi_write_force_png_filter = filter;
        ok = stbi_write_png_to_func(byte_buf_append, &b, width, height, channels, px, width * channels);
        stbi_write_force_png_filter = -1;
    }
    int status;
    if (!ok || b.failed)
        status = rs_err_set(err, RS_ERR_SYSTEM, path, 0, "cannot encode the PNG (out of memory)");
    else
        status = rs_write_file_atomic(path, b.p, b.n, err);
    free(b.p);
    return status;
}

int rs_image_write_png8(const unsigned char *px, int width, int height, int channels, const char *path, rs_err *err)
{
    return write_png8(px, width, height, channels, 1, path, err); /* Sub for every row: no choosing */
}

unsigned char *rs_image_ldr_codes_mem(const void *data, size_t size, const char *name, int *width, int *height,
                                      rs_err *err)
{
    const unsigned char *p = data;
    const char *kind = size >= 8 && memcmp(p, "\x89PNG\r\n\x1a\n", 8) == 0 ? "PNG"
        : size >= 3 && p[0] == 0xff && p[1] == 0xd8 && p[2] == 0xff        ? "JPEG"
                                                                           : NULL;
    if (!kind) {
        rs_err_set(err, RS_ERR_INPUT, name, 0, "neither a PNG nor a JPEG (the data does not start like one)");
        return NULL;
    }
    int w = 0, h = 0, comp = 0;
    if (ldr_check(data, size, name, kind, &w, &h, err) != 0) return NULL;
    unsigned char *px = stbi_load_from_memory(data, (int)size, &w, &h, &comp, 3);
    if (!px) {
        rs_err_set(err, RS_ERR_INPUT, name, 0, "%s: %s", kind, stbi_failure_reason());
        return NULL;
    }
    unsigned char *out = malloc((size_t)w * (size_t)h * 3);
    if (!out)
        rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory");
    else
        memcpy(out, px, (size_t)w * (size_t)h * 3);
    stbi_image_free(px);
    *width = w;
    *height = h;
    return out;
}

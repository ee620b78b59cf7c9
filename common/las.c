/* las: the ASPRS LAS reader (see las.h). The header layout is the LAS 1.4 specification's
 * (R15, table 3), whose first 227 bytes are those of 1.0 to 1.2; 1.3 adds the waveform start
 * (235 bytes), 1.4 the EVLRs and the 64-bit counts (375 bytes). All fields are little-endian. */
#define _DEFAULT_SOURCE /* madvise's MADV_HUGEPAGE */
#include "common/las.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>

#include "common/log.h"

/* The largest public header read; LAS 1.4's. */
#define HEADER_MAX  375
#define CHUNK_BYTES (4u << 20)
#define VLR_HEADER  54
#define LAZ_HOWTO                                                                                    \
    "LAZ is compressed LAS, which rhoscan cannot read yet: decompress it first, e.g. with LAStools " \
    "(laszip -i FILE.laz -o FILE.las) or PDAL (pdal translate FILE.laz FILE.las), and give the .las file"

struct rs_las {
    FILE *fp;
    char path[4096];
    rs_las_info info;
    uint64_t next;   /* index of the next point to read */
    size_t capacity; /* points per chunk */
    unsigned char *raw;
    rs_las_chunk chunk;
};

/* The bytes of the format's own fields (LAS 1.4 R15, tables 7 to 17). */
static const unsigned min_record[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
/* Where RGB starts in the formats that have it, 0 for none. */
static const unsigned rgb_at[11] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};

static uint16_t le16(const unsigned char *p)
{
    return (uint16_t)(p[0] | p[1] << 8);
}
static uint32_t le32(const unsigned char *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}
static uint64_t le64(const unsigned char *p)
{
    return (uint64_t)le32(p) | (uint64_t)le32(p + 4) << 32;
}
static int32_t le32s(const unsigned char *p)
{
    uint32_t u = le32(p);
    int32_t s;
    memcpy(&s, &u, sizeof s);
    return s;
}
static double le_double(const unsigned char *p)
{
    uint64_t u = le64(p);
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

/* The header's sizes and offsets: the version's header fits, the point offset is not inside
 * the header and not past the end of the file. */
static int check_layout(const rs_las_info *in, const char *path, rs_err *err)
{
    if (in->version_major != 1 || in->version_minor > 4)
        return rs_err_set(err, RS_ERR_INPUT, path, 0, "LAS header, offset 24: version %d.%d; expected 1.0 to 1.4",
                          in->version_major, in->version_minor);
    unsigned need = in->version_minor >= 4 ? 375 : in->version_minor == 3 ? 235 : 227;
    if (in->header_size < need)
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "LAS header, offset 94: header size %u; expected at least %u for LAS %d.%d", in->header_size,
                          need, in->version_major, in->version_minor);
    if (in->header_size > in->file_size)
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "LAS header, offset 94: header size %u; the file has only %llu bytes (truncated?)",
                          in->header_size, (unsigned long long)in->file_size);
    if (in->offset_to_points < in->header_size || in->offset_to_points > in->file_size)
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "LAS header, offset 96: offset to point data %u; expected from the header size (%u) to the "
                          "file size (%llu)",
                          in->offset_to_points, in->header_size, (unsigned long long)in->file_size);
    return 0;
}

/* The point format, its record length, the scales and offsets, and the points' bytes. */
static int check_points(const rs_las_info *in, const char *path, rs_err *err)
{
    if (in->format > 10)
        return rs_err_set(err, RS_ERR_INPUT, path, 0, "LAS header, offset 104: point data format %d; expected 0 to 10",
                          in->format);
    if (in->record_length < min_record[in->format])
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "LAS header, offset 105: point record length %u; expected at least %u for point format %d",
                          in->record_length, min_record[in->format], in->format);
    static const char *axis = "XYZ";
    for (int j = 0; j < 3; j++) {
        if (!isfinite(in->scale[j]) || in->scale[j] == 0 || fabs(in->scale[j]) > 1e6)
            return rs_err_set(err, RS_ERR_INPUT, path, 0,
                              "LAS header, offset %d: %c scale factor %g; expected a finite non-zero scale",
                              131 + 8 * j, axis[j], in->scale[j]);
        if (!isfinite(in->offset[j]) || fabs(in->offset[j]) > RS_CLOUD_MAX_M)
            return rs_err_set(err, RS_ERR_INPUT, path, 0,
                              "LAS header, offset %d: %c offset %g; expected a finite offset within %g m", 155 + 8 * j,
                              axis[j], in->offset[j], RS_CLOUD_MAX_M);
    }
    uint64_t room = in->file_size - in->offset_to_points;
    if (in->npoints > room / in->record_length)
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "LAS header: %llu points of %u bytes from offset %u need %.0f bytes; the file has %llu "
                          "(truncated, or a count that lies)",
                          (unsigned long long)in->npoints, in->record_length, in->offset_to_points,
                          (double)in->offset_to_points + (double)in->npoints * in->record_length,
                          (unsigned long long)in->file_size);
    return 0;
}

/* The public header block from its bytes (n of them read, at least 227). */
static int parse_header(const unsigned char *h, size_t n, rs_las_info *in, const char *path, rs_err *err)
{
    in->global_encoding = le16(h + 6);
    in->version_major = h[24];
    in->version_minor = h[25];
    in->header_size = le16(h + 94);
    in->offset_to_points = le32(h + 96);
    in->nvlrs = le32(h + 100);
    if (h[104] & 0xc0)
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "offset 104: point data format byte %u has the compression bit: %s", h[104], LAZ_HOWTO);
    in->format = h[104];
    in->record_length = le16(h + 105);
    uint32_t legacy = le32(h + 107);
    for (int j = 0; j < 3; j++) {
        in->scale[j] = le_double(h + 131 + 8 * j);
        in->offset[j] = le_double(h + 155 + 8 * j);
        in->max[j] = le_double(h + 179 + 16 * j);
        in->min[j] = le_double(h + 187 + 16 * j);
    }
    if (check_layout(in, path, err) != 0) return -1;
    in->npoints = legacy;
    if (in->version_minor >= 4 && n >= HEADER_MAX) {
        uint64_t wide = le64(h + 247);
        if (wide != 0) {
            if (legacy != 0 && legacy != wide)
                rs_log_warn("%s: the legacy point count (%u) and the 64-bit one (%llu) differ: the 64-bit one is used",
                            path, legacy, (unsigned long long)wide);
            in->npoints = wide;
        }
    }
    in->has_rgb = in->format <= 10 && rgb_at[in->format] != 0;
    return check_points(in, path, err);
}

/* The bytes of a VLR (or EVLR) body rhoscan reads: the GeoTIFF keys and the WKT. */
typedef struct crs_vlrs {
    uint8_t *geokeys, *ascii;
    char *wkt;
    size_t ngeokeys, nascii, nwkt;
} crs_vlrs;

/* Reads the body of record id at offset at (length len) when it is one of the CRS records. */
static int keep_crs(rs_las *f, const unsigned char *user, int id, uint64_t at, uint64_t len, crs_vlrs *cv, rs_err *err)
{
    uint8_t **slot = NULL;
    size_t *nslot = NULL;
    if (memcmp(user, "LASF_Projection", 15) != 0 && !(memcmp(user, "liblas", 6) == 0 && id == 2112)) return 0;
    if (id == 34735) slot = &cv->geokeys, nslot = &cv->ngeokeys;
    if (id == 34737) slot = &cv->ascii, nslot = &cv->nascii;
    if (id == 2112 && !cv->wkt) slot = (uint8_t **)&cv->wkt, nslot = &cv->nwkt;
    if (!slot || *slot || len == 0 || len > (1u << 20) || at + len > f->info.file_size) return 0;
    uint8_t *b = malloc((size_t)len + 1);
    if (!b) return rs_err_set(err, RS_ERR_SYSTEM, f->path, 0, "out of memory");
    if (fseeko(f->fp, (off_t)at, SEEK_SET) != 0 || fread(b, 1, (size_t)len, f->fp) != (size_t)len) {
        free(b);
        return rs_err_errno(err, f->path, "cannot read a coordinate-system VLR");
    }
    b[len] = 0;
    *slot = b;
    *nslot = (size_t)len;
    return 0;
}

/* LAS 1.4's EVLRs (after the points), for a WKT kept there. */
static int read_evlrs(rs_las *f, const unsigned char *h, size_t n, crs_vlrs *cv, rs_err *err)
{
    if (f->info.version_minor < 4 || n < HEADER_MAX) return 0;
    uint64_t at = le64(h + 235);
    uint32_t count = le32(h + 243);
    for (uint32_t k = 0; k < count && at != 0; k++) {
        unsigned char v[60];
        if (at + 60 > f->info.file_size || fseeko(f->fp, (off_t)at, SEEK_SET) != 0 || fread(v, 1, 60, f->fp) != 60) {
            rs_log_warn("%s: EVLR %u of %u at offset %llu runs past the file: the rest are not read", f->path, k + 1,
                        count, (unsigned long long)at);
            return 0;
        }
        uint64_t len = le64(v + 20);
        if (keep_crs(f, v + 2, le16(v + 18), at + 60, len, cv, err) != 0) return -1;
        if (len > f->info.file_size) break;
        at += 60 + len;
    }
    return 0;
}

/* The coordinate system from the records kept: WKT when the global encoding's WKT bit (4) is
 * set or there are no GeoTIFF keys, else the GeoTIFF keys. Units other than metres are
 * converted; a geographic system (degrees) or an unknown unit is refused. */
static int decide_crs(rs_las *f, const crs_vlrs *cv, rs_err *err)
{
    rs_las_info *in = &f->info;
    rs_las_crs *crs = &in->crs;
    memset(crs, 0, sizeof *crs);
    crs->source = "";
    crs->unit_m = crs->vunit_m = 1;
    int use_wkt = cv->wkt && ((in->global_encoding & 16) || !cv->geokeys);
    if (use_wkt ? rs_las_crs_wkt(cv->wkt, cv->nwkt, crs) != 0
                : cv->geokeys &&
                rs_las_crs_geokeys(cv->geokeys, cv->ngeokeys, (const char *)cv->ascii, cv->nascii, crs) != 0)
        rs_log_warn("%s: its %s cannot be read: the coordinates are taken as metres", f->path,
                    use_wkt ? "WKT coordinate system" : "GeoTIFF key directory");
    if (crs->kind == RS_LAS_CRS_GEOGRAPHIC && in->npoints > 0) /* without points: "no points" says more */
        return rs_err_set(err, RS_ERR_INPUT, f->path, 0,
                          "its coordinate system (%s, from the %s) is geographic: the coordinates are longitude and "
                          "latitude in degrees; expected a projected system in metres or feet (reproject it first, "
                          "e.g. pdal translate with filters.reprojection)",
                          crs->name[0] ? crs->name : "unnamed", crs->source);
    if (crs->unknown_unit || !(crs->unit_m > 0) || !(crs->vunit_m > 0))
        return rs_err_set(err, RS_ERR_INPUT, f->path, 0,
                          "its coordinate system (%s, from the %s) has a linear unit rhoscan does not know (%s%s%d); "
                          "expected metres, feet (9002), US survey feet (9003), Clarke's feet (9005) or kilometres",
                          crs->name[0] ? crs->name : "unnamed", crs->source, crs->unit,
                          crs->unit[0] ? ", code " : "code ", crs->unit_code);
    in->unit_m[0] = in->unit_m[1] = crs->unit_m;
    in->unit_m[2] = crs->vunit_m;
    return 0;
}

/* The VLRs between the header and the point data: a "laszip encoded" one (record 22204) marks a
 * LAZ file whose format byte was cleared; the GeoTIFF and WKT ones give the coordinate system.
 * A VLR list that runs past the point offset ends the walk with a warning (the points are where
 * the header says). */
static int check_vlrs(rs_las *f, const unsigned char *h, size_t n, rs_err *err)
{
    uint64_t at = f->info.header_size;
    crs_vlrs cv = {0};
    int rc = -1;
    for (uint32_t k = 0; k < f->info.nvlrs; k++) {
        unsigned char v[VLR_HEADER];
        if (at + VLR_HEADER > f->info.offset_to_points || fseeko(f->fp, (off_t)at, SEEK_SET) != 0 ||
            fread(v, 1, VLR_HEADER, f->fp) != VLR_HEADER) {
            rs_log_warn("%s: VLR %u of %u at offset %llu does not fit before the point data (offset %u): the rest "
                        "are not read",
                        f->path, k + 1, f->info.nvlrs, (unsigned long long)at, f->info.offset_to_points);
            break;
        }
        if (memcmp(v + 2, "laszip encoded", 14) == 0 && le16(v + 18) == 22204) {
            rs_err_set(err, RS_ERR_INPUT, f->path, 0, "offset %llu: a \"laszip encoded\" VLR (record 22204): %s",
                       (unsigned long long)at, LAZ_HOWTO);
            goto out;
        }
        uint64_t len = le16(v + 20);
        if (at + VLR_HEADER + len <= f->info.offset_to_points &&
            keep_crs(f, v + 2, le16(v + 18), at + VLR_HEADER, len, &cv, err) != 0)
            goto out;
        at += VLR_HEADER + len;
    }
    rc = read_evlrs(f, h, n, &cv, err) != 0 || decide_crs(f, &cv, err) != 0 ? -1 : 0;
out:
    free(cv.geokeys);
    free(cv.ascii);
    free(cv.wkt);
    return rc;
}

static int open_file(rs_las *f, const char *path, unsigned char *h, size_t *n, rs_err *err)
{
    snprintf(f->path, sizeof f->path, "%s", path);
    f->fp = fopen(path, "rb");
    if (!f->fp) return rs_err_errno(err, path, "cannot open the LAS file");
    struct stat st;
    if (fstat(fileno(f->fp), &st) != 0) return rs_err_errno(err, path, "cannot stat the LAS file");
    f->info.file_size = (uint64_t)st.st_size;
    *n = fread(h, 1, HEADER_MAX, f->fp);
    if (*n < 4 || memcmp(h, "LASF", 4) != 0)
        return rs_err_set(err, RS_ERR_INPUT, path, 0, "offset 0: expected the LAS signature \"LASF\"");
    if (*n < 227)
        return rs_err_set(err, RS_ERR_INPUT, path, 0,
                          "the file has %zu bytes: a LAS public header needs at least 227 (truncated?)", *n);
    return 0;
}

static int alloc_chunk(rs_las *f, rs_err *err)
{
    size_t cap = CHUNK_BYTES / f->info.record_length;
    if (cap < 1) cap = 1;
    if (f->info.npoints < cap) cap = (size_t)f->info.npoints ? (size_t)f->info.npoints : 1;
    f->capacity = cap;
    f->raw = malloc(cap * f->info.record_length);
    f->chunk.xyz = malloc(cap * 3 * sizeof *f->chunk.xyz);
    f->chunk.intensity = malloc(cap * sizeof *f->chunk.intensity);
    f->chunk.classification = malloc(cap);
    f->chunk.withheld = malloc(cap);
    f->chunk.rgb = f->info.has_rgb ? malloc(cap * 3 * sizeof *f->chunk.rgb) : NULL;
    if (!f->raw || !f->chunk.xyz || !f->chunk.intensity || !f->chunk.classification || !f->chunk.withheld ||
        (f->info.has_rgb && !f->chunk.rgb))
        return rs_err_set(err, RS_ERR_SYSTEM, f->path, 0, "out of memory for a chunk of %zu points", cap);
    return 0;
}

rs_las *rs_las_open(const char *path, rs_err *err)
{
    rs_las *f = calloc(1, sizeof *f);
    if (!f) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
        return NULL;
    }
    unsigned char h[HEADER_MAX];
    size_t n = 0;
    if (open_file(f, path, h, &n, err) != 0 || parse_header(h, n, &f->info, path, err) != 0 ||
        check_vlrs(f, h, n, err) != 0 || alloc_chunk(f, err) != 0)
        goto fail;
    if (fseeko(f->fp, (off_t)f->info.offset_to_points, SEEK_SET) != 0) {
        rs_err_errno(err, path, "cannot seek to the point data");
        goto fail;
    }
    return f;
fail:
    rs_las_close(f);
    return NULL;
}

const rs_las_info *rs_las_info_of(const rs_las *f)
{
    return &f->info;
}

/* Decodes n records of raw into the chunk, the coordinates into xyz (the chunk's or the
 * caller's); -1 (err set) for a coordinate beyond RS_CLOUD_MAX_M. */
static int decode(rs_las *f, size_t n, double *xyz, rs_err *err)
{
    const rs_las_info *in = &f->info;
    const unsigned rec = in->record_length, rgb = rgb_at[in->format];
    const int wide = in->format >= 6; /* formats 6-10: the class has a byte of its own, at 16 */
    rs_las_chunk *c = &f->chunk;
    for (size_t i = 0; i < n; i++) {
        const unsigned char *p = f->raw + i * rec;
        for (int j = 0; j < 3; j++) {
            double v = (le32s(p + 4 * j) * in->scale[j] + in->offset[j]) * in->unit_m[j];
            if (!(fabs(v) <= RS_CLOUD_MAX_M))
                return rs_err_set(err, RS_ERR_INPUT, f->path, 0,
                                  "point %llu (offset %llu): coordinate %c = %g; expected at most %g m (scale or "
                                  "offset wrong?)",
                                  (unsigned long long)(f->next + i),
                                  (unsigned long long)(in->offset_to_points + (f->next + i) * rec), "xyz"[j], v,
                                  RS_CLOUD_MAX_M);
            xyz[3 * i + j] = v;
        }
        c->intensity[i] = le16(p + 12);
        c->classification[i] = wide ? p[16] : p[15] & 0x1f;
        c->withheld[i] = wide ? (p[15] >> 2) & 1 : p[15] >> 7;
        if (rgb)
            for (int j = 0; j < 3; j++) c->rgb[3 * i + j] = le16(p + rgb + 2 * j);
    }
    return 0;
}

/* rs_las_next with the coordinates decoded into xyz (room for a chunk), NULL: the chunk's. */
static const rs_las_chunk *next_into(rs_las *f, double *xyz, rs_err *err)
{
    uint64_t left = f->info.npoints - f->next;
    size_t n = left < f->capacity ? (size_t)left : f->capacity;
    f->chunk.n = 0;
    if (n == 0) return &f->chunk;
    size_t got = fread(f->raw, f->info.record_length, n, f->fp);
    if (got != n) {
        if (ferror(f->fp)) {
            rs_err_errno(err, f->path, "cannot read the point records");
            return NULL;
        }
        rs_err_set(err, RS_ERR_INPUT, f->path, 0,
                   "the file ends in point %llu of %llu (offset %llu); expected %llu bytes of points from offset %u",
                   (unsigned long long)(f->next + got), (unsigned long long)f->info.npoints,
                   (unsigned long long)(f->info.offset_to_points + (f->next + got) * f->info.record_length),
                   (unsigned long long)(f->info.npoints * f->info.record_length), f->info.offset_to_points);
        return NULL;
    }
    if (decode(f, n, xyz ? xyz : f->chunk.xyz, err) != 0) return NULL;
    f->next += n;
    f->chunk.n = n;
    return &f->chunk;
}

const rs_las_chunk *rs_las_next(rs_las *f, rs_err *err)
{
    return next_into(f, NULL, err);
}

void rs_las_close(rs_las *f)
{
    if (!f) return;
    if (f->fp) fclose(f->fp);
    free(f->raw);
    free(f->chunk.xyz);
    free(f->chunk.intensity);
    free(f->chunk.rgb);
    free(f->chunk.classification);
    free(f->chunk.withheld);
    free(f);
}

int rs_las_parse_classes(const char *text, uint8_t keep[256], rs_err *err)
{
    memset(keep, 0, 256);
    int count = 0;
    for (const char *s = text;;) {
        s += strspn(s, " \t,");
        if (!*s) break;
        char *end;
        errno = 0;
        long v = strtol(s, &end, 10);
        if (end == s || errno || v < 0 || v > 255 || (*end && !strchr(" \t,", *end)))
            return rs_err_set(
                err, RS_ERR_INPUT, NULL, 0,
                "[ingest] las_classes = \"%.200s\": \"%.*s\" is not a class number; expected class numbers "
                "0 to 255 separated by spaces (e.g. \"2 6\": ground and buildings)",
                text, (int)strcspn(s, " \t,"), s);
        keep[v] = 1;
        count++;
        s = end;
    }
    if (count == 0)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                          "[ingest] las_classes is empty; expected class numbers 0 to 255 separated by spaces (e.g. "
                          "\"2 6\"), or leave the key out to keep every class");
    return 0;
}

/* The classes present (histogram counts > 0) as "2 (120 points), 6 (40 points)" into buf. */
static void list_classes(const uint64_t *hist, char *buf, size_t size)
{
    size_t len = 0;
    buf[0] = '\0';
    for (int k = 0; k < 256 && len + 1 < size; k++)
        if (hist[k])
            len += (size_t)snprintf(buf + len, size - len, "%s%d (%llu points)", len ? ", " : "", k,
                                    (unsigned long long)hist[k]);
}

/* Colour into 8 bits as it streams in: while every value seen is <= 255 the values are kept as
 * they are (8-bit colour in the 16-bit fields); the first value above 255 shows 16-bit colour,
 * and from then on the high byte is kept, the values kept before becoming theirs (0: they were
 * all below 256). One pass, no second copy. */
typedef struct rgb_state {
    int wide;
} rgb_state;

static void put_rgb(rgb_state *s, uint8_t *rgb, size_t kept, const uint16_t *v)
{
    if (!s->wide && (v[0] > 255 || v[1] > 255 || v[2] > 255)) {
        s->wide = 1;
        memset(rgb, 0, 3 * kept);
    }
    for (int j = 0; j < 3; j++) rgb[3 * kept + j] = (uint8_t)(s->wide ? v[j] >> 8 : v[j]);
}

/* Large arrays in 2 MiB pages where the kernel gives them on request (Debian's default,
 * transparent huge pages in "madvise" mode): filling a 10^8-point cloud otherwise takes 750000
 * page faults. Only a hint; nothing changes when it is refused. */
static void *alloc_big(size_t bytes)
{
    void *p = malloc(bytes);
#ifdef MADV_HUGEPAGE
    size_t page = 2u << 20;
    if (p && bytes >= 4 * page) {
        uintptr_t from = ((uintptr_t)p + page - 1) & ~(uintptr_t)(page - 1),
                  to = ((uintptr_t)p + bytes) & ~(uintptr_t)(page - 1);
        if (to > from) madvise((void *)from, to - from, MADV_HUGEPAGE);
    }
#endif
    return p;
}

/* The chunks of f into c (allocated for every point), the classes kept by keep. The coordinates
 * are decoded straight into c (the points of a chunk from the first free slot on, then moved
 * down over the ones not kept): the chunk holds only the small fields. */
static int fill(rs_las *f, rs_cloud *c, const uint8_t *keep, int keep_withheld, uint64_t *withheld, uint64_t *hist,
                rgb_state *rs, rs_err *err)
{
    const rs_las_info *in = rs_las_info_of(f);
    char what[160];
    snprintf(what, sizeof what, "reading %.120s", f->path);
    rs_progress *p = in->npoints >= 1000000 ? rs_progress_start(what, (size_t)in->npoints) : NULL;
    size_t kept = 0;
    int rc = -1;
    for (;;) {
        size_t base = kept;
        const rs_las_chunk *ch = next_into(f, c->xyz + 3 * base, err);
        if (!ch) goto out;
        if (ch->n == 0) break;
        for (size_t i = 0; i < ch->n; i++) {
            if (ch->withheld[i] && !keep_withheld) {
                (*withheld)++;
                continue;
            }
            hist[ch->classification[i]]++;
            if (keep && !keep[ch->classification[i]]) continue;
            if (kept != base + i) memcpy(c->xyz + 3 * kept, c->xyz + 3 * (base + i), 3 * sizeof *c->xyz);
            c->intensity[kept] = ch->intensity[i];
            if (c->rgb) put_rgb(rs, c->rgb, kept, ch->rgb + 3 * i);
            kept++;
        }
        if (p) rs_progress_add(p, ch->n);
    }
    rc = 0;
out:
    if (p) rs_progress_end(p);
    c->npoints = kept;
    memset(c->valid, 1, kept);
    return rc;
}

rs_cloud *rs_las_read(const char *path, const uint8_t *keep, rs_err *err)
{
    return rs_las_read_with(path, keep, 0, NULL, err);
}

rs_cloud *rs_las_read_with(const char *path, const uint8_t *keep, int keep_withheld, uint64_t *withheld_out,
                           rs_err *err)
{
    uint64_t withheld = 0;
    rs_las *f = rs_las_open(path, err);
    if (!f) return NULL;
    const rs_las_info *in = rs_las_info_of(f);
    rs_cloud *c = calloc(1, sizeof *c);
    uint64_t *hist = calloc(256, sizeof *hist);
    rgb_state rs = {0};
    if (!c || !hist || in->npoints > SIZE_MAX / 64) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory for %llu points", (unsigned long long)in->npoints);
        goto fail;
    }
    /* Not rs_cloud_resize: it would zero the arrays, a pass over the memory that fill makes anyway. */
    size_t n = in->npoints ? (size_t)in->npoints : 1;
    c->xyz = alloc_big(n * 3 * sizeof *c->xyz);
    c->intensity = alloc_big(n * sizeof *c->intensity);
    c->valid = alloc_big(n);
    c->rgb = in->has_rgb ? alloc_big(n * 3) : NULL;
    if (!c->xyz || !c->intensity || !c->valid || (in->has_rgb && !c->rgb)) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory for %llu points", (unsigned long long)in->npoints);
        goto fail;
    }
    if (fill(f, c, keep, keep_withheld, &withheld, hist, &rs, err) != 0) goto fail;
    if (withheld_out) *withheld_out = withheld;
    if (c->npoints == 0 && withheld > 0 && withheld == in->npoints) {
        rs_err_set(err, RS_ERR_INPUT, path, 0,
                   "every one of its %llu points is flagged withheld (not to be used); expected points to keep, or "
                   "[ingest] las_withheld = keep",
                   (unsigned long long)in->npoints);
        goto fail;
    }
    if (keep && c->npoints == 0 && in->npoints > 0) {
        char classes[512];
        list_classes(hist, classes, sizeof classes);
        rs_err_set(err, RS_ERR_INPUT, path, 0,
                   "no point of the %llu has a class listed in [ingest] las_classes; the file's classes: %s",
                   (unsigned long long)in->npoints, classes);
        goto fail;
    }
    if (c->npoints < in->npoints && c->npoints > 0) /* shrink to the points kept; cannot fail in practice */
        rs_cloud_resize(c, c->npoints, 0, 0, err);
    c->normals_up = 1;
    char crs[320];
    rs_las_crs_describe(&in->crs, crs, sizeof crs);
    rs_log_info("%s: LAS %d.%d, point format %d (%u-byte records), %zu of %llu points kept%s; %llu withheld %s", path,
                in->version_major, in->version_minor, in->format, in->record_length, c->npoints,
                (unsigned long long)in->npoints,
                !in->has_rgb  ? ""
                    : rs.wide ? ", 16-bit colour (high byte kept)"
                              : ", 8-bit colour stored in 16-bit fields",
                (unsigned long long)withheld, keep_withheld ? "kept" : "dropped");
    rs_log_info("%s: coordinate system: %s%s", path, crs,
                in->unit_m[0] != 1 || in->unit_m[2] != 1 ? "; converted to metres" : "");
    free(hist);
    rs_las_close(f);
    return c;
fail:
    free(hist);
    rs_cloud_free(c);
    rs_las_close(f);
    return NULL;
}

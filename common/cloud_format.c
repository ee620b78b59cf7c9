/* cloud_format: the table of point-cloud formats (see cloud_format.h): {name, magic test,
 * extensions, reader}, magic bytes first, extension second, PTX last. */
#include "common/cloud_format.h"

#include <stdio.h>
#include <string.h>
#include <strings.h>

#include "common/cloud_ply.h"
#include "common/cloud_text.h"
#include "common/e57.h"
#include "common/las.h"
#include "common/pcl_bridge.h"
#include "common/ptx.h"

/* Bytes read to tell the formats apart: LAS keeps its point format at byte 104. */
#define HEAD_SIZE 256
#define READABLE  "expected E57, LAS, PTX, PLY, PCD or XYZ/CSV text (convert it, e.g. with PDAL or CloudCompare)"

typedef struct cloud_format {
    const char *name;
    /* The file starts with the format's magic bytes (head: its first n bytes; path for LAZ,
     * which is LAS by its magic). NULL: the format has none and is known by extension. */
    int (*is_a)(const unsigned char *head, size_t n, const char *path);
    const char *extensions; /* space-separated, with the dot; choose the reader only when is_a is NULL */
    rs_cloud *(*read)(const char *path, const rs_cloud_read_opts *opts, rs_err *err);
    const char *refusal; /* when read is NULL: why the file is not read */
} cloud_format;

/* The extension of path (from its last dot, case ignored) is one of extensions. */
static int has_extension(const char *path, const char *extensions)
{
    const char *dot = strrchr(path, '.');
    if (!dot || strchr(dot, '/')) return 0;
    size_t len = strlen(dot);
    for (const char *e = extensions; *e; e += strspn(e, " ")) {
        size_t elen = strcspn(e, " ");
        if (elen == len && strncasecmp(e, dot, len) == 0) return 1;
        e += elen;
    }
    return 0;
}

static int ply_is_a(const unsigned char *p, size_t n, const char *path)
{
    return n >= 4 && memcmp(p, "ply", 3) == 0 && (p[3] == '\n' || p[3] == '\r');
}

static int e57_is_a(const unsigned char *p, size_t n, const char *path)
{
    return n >= 8 && memcmp(p, "ASTM-E57", 8) == 0;
}

static int las_is_a(const unsigned char *p, size_t n, const char *path)
{
    return n >= 4 && memcmp(p, "LASF", 4) == 0;
}

/* LASzip marks a compressed file by bit 7 (some writers bit 6) of the point data format id; a
 * file that clears it but keeps the "laszip encoded" VLR is refused by the LAS reader. */
static int laz_is_a(const unsigned char *p, size_t n, const char *path)
{
    return las_is_a(p, n, path) && n > 104 && (p[104] & 0xc0);
}

static rs_cloud *read_ply(const char *path, const rs_cloud_read_opts *opts, rs_err *err)
{
    return rs_cloud_read_ply(path, err);
}

static rs_cloud *read_pcd(const char *path, const rs_cloud_read_opts *opts, rs_err *err)
{
    return rs_pcl_read_pcd(path, err);
}

static rs_cloud *read_text(const char *path, const rs_cloud_read_opts *opts, rs_err *err)
{
    return rs_cloud_read_text(path, opts->columns, err);
}

/* LAZ too: rs_las_open refuses it, saying how to decompress it. */
static rs_cloud *read_las(const char *path, const rs_cloud_read_opts *opts, rs_err *err)
{
    uint64_t withheld = 0;
    rs_cloud *c = rs_las_read_with(path, opts->las_keep, opts->las_keep_withheld, &withheld, err);
    if (opts->las_withheld) *opts->las_withheld = withheld;
    return c;
}

static rs_cloud *read_e57(const char *path, const rs_cloud_read_opts *opts, rs_err *err)
{
    return rs_e57_read(path, err);
}

static rs_cloud *read_ptx(const char *path, const rs_cloud_read_opts *opts, rs_err *err)
{
    return rs_ptx_read(path, err);
}

/* In the order of the tests: LAZ before LAS, whose magic it shares; PTX, the fallback, last.
 * PCD is known by extension only, as XYZ text: its header is text that a text cloud's
 * comment lines could hold too. */
static const cloud_format formats[] = {
    {"PLY", ply_is_a, ".ply", read_ply, NULL}, {"E57", e57_is_a, ".e57", read_e57, NULL},
    {"LAZ", laz_is_a, ".laz", read_las, NULL}, {"LAS", las_is_a, ".las", read_las, NULL},
    {"PCD", NULL, ".pcd", read_pcd, NULL},     {"text", NULL, ".xyz .txt .csv .pts", read_text, NULL},
    {"PTX", NULL, ".ptx", read_ptx, NULL},
};
enum { NFORMATS = sizeof formats / sizeof formats[0] };

/* The first HEAD_SIZE bytes of path, as many as there are; 0 when it cannot be read (the
 * reader chosen then says why, as it would have anyway). */
static size_t read_head(const char *path, unsigned char *head)
{
    FILE *fp = fopen(path, "rb");
    if (!fp) return 0;
    size_t n = fread(head, 1, HEAD_SIZE, fp);
    fclose(fp);
    return n;
}

/* The format of path; *n: the bytes of its head that were read. */
static const cloud_format *format_of(const char *path, size_t *n_read)
{
    unsigned char head[HEAD_SIZE];
    size_t n = *n_read = read_head(path, head);
    for (int f = 0; f < NFORMATS; f++)
        if (formats[f].is_a && formats[f].is_a(head, n, path)) return &formats[f];
    for (int f = 0; f < NFORMATS; f++)
        if (!formats[f].is_a && has_extension(path, formats[f].extensions)) return &formats[f];
    return &formats[NFORMATS - 1];
}

/* The format with magic bytes that path's name claims, or NULL. */
static const cloud_format *claimed_by_name(const char *path)
{
    for (int f = 0; f < NFORMATS; f++)
        if (formats[f].is_a && has_extension(path, formats[f].extensions)) return &formats[f];
    return NULL;
}

rs_cloud *rs_cloud_read_with(const char *path, const rs_cloud_read_opts *opts, const char **format, rs_err *err)
{
    static const rs_cloud_read_opts defaults = {0};
    size_t n;
    const cloud_format *f = format_of(path, &n);
    if (format) *format = f->name;
    if (!f->read) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "%s: " READABLE, f->refusal);
        return NULL;
    }
    rs_cloud *c = f->read(path, opts ? opts : &defaults, err);
    const cloud_format *claimed = c || n == 0 ? NULL : claimed_by_name(path);
    if (claimed && claimed != f && err) { /* e.g. a damaged .las read as PTX: say why it was not a LAS */
        size_t len = strlen(err->msg);
        snprintf(err->msg + len, sizeof err->msg - len,
                 " (read as %s: the name says %s but the file does not start like one)", f->name, claimed->name);
    }
    return c;
}

rs_cloud *rs_cloud_read(const char *path, rs_err *err)
{
    return rs_cloud_read_with(path, NULL, NULL, err);
}

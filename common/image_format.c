/* image_format: the one place that maps an image file to its reader or writer, a table in the
 * manner of libvips' foreign/: each format has a magic test, its extensions and its read and
 * write functions. Reading goes by magic bytes (every format read has them); the extension
 * chooses the writer and, when the bytes match no format, explains the refusal. Defines the
 * file functions declared in image.h. */
#include "common/image.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "common/fileio.h"
#include "common/image_exr.h"
#include "common/image_stb.h"

#define FORMATS "an OpenEXR, Radiance .hdr, PNG or JPEG image"

typedef struct image_format {
    const char *name;
    int (*is_a)(const unsigned char *p, size_t n); /* the file starts with the format's magic */
    const char *extensions;                        /* space-separated, with the dot */
    rs_image *(*read)(const void *data, size_t size, const char *name, rs_err *err);
    int (*write)(const rs_image *img, const char *path, const rs_image_write_opts *opts, rs_err *err); /* or NULL */
} image_format;

static int exr_is_a(const unsigned char *p, size_t n)
{
    static const unsigned char magic[4] = {0x76, 0x2f, 0x31, 0x01};
    return n >= 4 && memcmp(p, magic, 4) == 0;
}

static int hdr_is_a(const unsigned char *p, size_t n)
{
    return (n >= 10 && memcmp(p, "#?RADIANCE", 10) == 0) || (n >= 6 && memcmp(p, "#?RGBE", 6) == 0);
}

static int png_is_a(const unsigned char *p, size_t n)
{
    static const unsigned char magic[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    return n >= 8 && memcmp(p, magic, 8) == 0;
}

static int jpeg_is_a(const unsigned char *p, size_t n)
{
    return n >= 3 && p[0] == 0xff && p[1] == 0xd8 && p[2] == 0xff;
}

static int write_exr(const rs_image *img, const char *path, const rs_image_write_opts *opts, rs_err *err)
{
    static const char *const rgb[] = {"R", "G", "B"}, *const y[] = {"Y"};
    const char *const *names = opts->names ? opts->names : img && img->channels == 3 ? rgb : y;
    if (!opts->names && img && img->channels != 1 && img->channels != 3)
        return rs_err_set(err, RS_ERR_INTERNAL, path, 0, "rs_image_write: %d channels and no names: expected 1 or 3",
                          img->channels);
    return rs_image_write_exr(img, path, names, opts->half, opts->note, err);
}

static int write_png(const rs_image *img, const char *path, const rs_image_write_opts *opts, rs_err *err)
{
    return rs_image_write_png(img, path, opts->scale != 0 ? opts->scale : 1.0f, err);
}

static const image_format formats[] = {
    {"OpenEXR", exr_is_a, ".exr", rs_image_exr_read_mem, write_exr},
    {"Radiance .hdr", hdr_is_a, ".hdr .pic", rs_image_hdr_read_mem, NULL},
    {"PNG", png_is_a, ".png", rs_image_png_read_mem, write_png},
    {"JPEG", jpeg_is_a, ".jpg .jpeg", rs_image_jpeg_read_mem, NULL},
};
enum { NFORMATS = sizeof formats / sizeof formats[0] };

/* The format whose extensions hold path's, or NULL. */
static const image_format *format_by_extension(const char *path)
{
    const char *dot = path ? strrchr(path, '.') : NULL;
    if (!dot || strchr(dot, '/')) return NULL;
    size_t len = strlen(dot);
    for (int f = 0; f < NFORMATS; f++)
        for (const char *e = formats[f].extensions; *e;) {
            size_t elen = strcspn(e, " ");
            if (elen == len && strncasecmp(e, dot, len) == 0) return &formats[f];
            e += elen;
            e += strspn(e, " ");
        }
    return NULL;
}

rs_image *rs_image_read_mem(const void *data, size_t size, const char *name, rs_err *err)
{
    const unsigned char *p = data;
    if (!name) name = "(memory)";
    if (!data || size == 0) {
        rs_err_set(err, RS_ERR_INPUT, name, 0, "empty file: expected " FORMATS);
        return NULL;
    }
    for (int f = 0; f < NFORMATS; f++)
        if (formats[f].is_a(p, size)) return formats[f].read(data, size, name, err);
    char first[40] = "";
    for (size_t i = 0, len = 0; i < size && i < 8; i++)
        len += (size_t)snprintf(first + len, sizeof first - len, "%s%02x", i ? " " : "", p[i]);
    const image_format *named = format_by_extension(name);
    rs_err_set(err, RS_ERR_INPUT, name, 0, "unknown file format (first bytes %s%s%s%s): expected " FORMATS, first,
               named ? "; the name says " : "", named ? named->name : "", named ? " but the content does not" : "");
    return NULL;
}

rs_image *rs_image_read(const char *path, rs_err *err)
{
    char *data = NULL;
    size_t size = 0;
    if (rs_read_file(path, &data, &size, err) != 0) return NULL;
    rs_image *img = rs_image_read_mem(data, size, path, err);
    free(data);
    return img;
}

int rs_image_write(const rs_image *img, const char *path, const rs_image_write_opts *opts, rs_err *err)
{
    static const rs_image_write_opts defaults = {0};
    const image_format *f = format_by_extension(path);
    if (!f || !f->write)
        return rs_err_set(err, RS_ERR_INPUT, path, 0, "cannot write %s: expected a name ending in .exr or .png",
                          f ? f->name : "this file type");
    return f->write(img, path, opts ? opts : &defaults, err);
}

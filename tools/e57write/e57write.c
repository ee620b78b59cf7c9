/* e57write: a small ASTM E57 writer for the tests and the bench (not installed).
 *
 *   e57write [--image FILE.png|.jpg [--image-pose "w x y z tx ty tz"] [--image-name NAME]
 *             [--pinhole "f pw ph cx cy"]]... in.ptx out.e57
 *       each PTX scan as an E57 scan: its points in the scanner's frame as the PTX lines give
 *       them (cartesianX/Y/Z and intensity as doubles, colour when the PTX has it), rowIndex and
 *       columnIndex (the PTX grid, column by column), cartesianInvalidState 2 for no-return
 *       "0 0 0" points, and the PTX matrix as the pose (unit quaternion + translation). Each --image
 *       embeds an 8-bit image with its pose (camera to world): an equirectangular one as a
 *       full-sphere sphericalRepresentation, or with --pinhole a pinholeRepresentation (focal
 *       length and pixel size in metres, principal point in pixels).
 *   e57write --synthetic N out.e57
 *       N points of cartesianX/Y/Z doubles (a helix), one unorganized scan: the bench's input.
 *
 * Written for the tests from the standard (ASTM E2807): pages of 1020 data bytes and a CRC-32C,
 * one compressed-vector section per scan with data packets of at most 64 KiB, bytestreams packed
 * least significant bit first; the XML last. Streams: memory does not grow with the points. */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/e57.h"

#define PI   3.14159265358979323846
#define PAGE 1024
#define DATA 1020

typedef struct writer {
    FILE *fp;
    uint8_t page[PAGE], page0[PAGE];
    size_t fill;      /* bytes in page */
    uint64_t logical; /* logical bytes written */
    uint64_t pages;   /* pages written */
} writer;

static void die(const char *msg)
{
    fprintf(stderr, "e57write: %s\n", msg);
    exit(1);
}

static void flush_page(writer *w)
{
    uint32_t c = rs_e57_crc32c(w->page, DATA);
    w->page[1020] = (uint8_t)(c >> 24), w->page[1021] = (uint8_t)(c >> 16), w->page[1022] = (uint8_t)(c >> 8);
    w->page[1023] = (uint8_t)c;
    if (w->pages++ == 0) memcpy(w->page0, w->page, PAGE); /* rewritten with the header at the end */
    if (fwrite(w->page, 1, PAGE, w->fp) != PAGE) die("write failed");
    memset(w->page, 0, PAGE);
    w->fill = 0;
}

static void put(writer *w, const void *data, size_t n)
{
    const uint8_t *p = data;
    while (n) {
        size_t take = DATA - w->fill < n ? DATA - w->fill : n;
        memcpy(w->page + w->fill, p, take);
        w->fill += take, w->logical += take, p += take, n -= take;
        if (w->fill == DATA) flush_page(w);
    }
}

static uint64_t physical(uint64_t logical)
{
    return logical / DATA * PAGE + logical % DATA;
}

static void put_u64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i));
}

/* One bit-packed field: its bytestream pending for the packet being built. */
typedef struct field {
    const char *xml; /* the prototype element */
    int bits;
    int64_t min; /* Integer: raw = value - min */
    int is_float;
    uint8_t *buf; /* this packet's bytes */
    size_t len;
    uint64_t acc; /* bits not yet whole bytes */
    int nacc;
} field;

static void field_push(field *f, double v)
{
    if (f->is_float) {
        memcpy(f->buf + f->len, &v, 8);
        f->len += 8;
        return;
    }
    uint64_t raw = (uint64_t)((int64_t)v - f->min);
    f->acc |= raw << f->nacc;
    f->nacc += f->bits;
    while (f->nacc >= 8) {
        f->buf[f->len++] = (uint8_t)f->acc;
        f->acc >>= 8;
        f->nacc -= 8;
    }
}

/* The data packet of the fields' pending bytes (the last one flushes partial bytes too). */
static void put_packet(writer *w, field *fs, int nf, int last)
{
    size_t len = 6 + 2 * (size_t)nf;
    for (int k = 0; k < nf; k++) {
        if (last && fs[k].nacc > 0) fs[k].buf[fs[k].len++] = (uint8_t)fs[k].acc, fs[k].nacc = 0, fs[k].acc = 0;
        len += fs[k].len;
    }
    size_t padded = (len + 3) & ~(size_t)3;
    if (padded > 65536) die("packet too large");
    uint8_t h[6 + 2 * 32] = {1, 0, (uint8_t)(padded - 1), (uint8_t)((padded - 1) >> 8), (uint8_t)nf, 0};
    for (int k = 0; k < nf; k++) h[6 + 2 * k] = (uint8_t)fs[k].len, h[7 + 2 * k] = (uint8_t)(fs[k].len >> 8);
    put(w, h, 6 + 2 * (size_t)nf);
    for (int k = 0; k < nf; k++) {
        put(w, fs[k].buf, fs[k].len);
        fs[k].len = 0;
    }
    static const uint8_t zero[4];
    put(w, zero, padded - len);
}

#define PER_PACKET 1200 /* records: 5 doubles + 3 bytes of integers each stay under 64 KiB */

typedef struct scan {
    int cols, rows, has_rgb;
    double T[16];    /* the PTX matrix (row-vector form) */
    double *v;       /* 7 values per point: x y z intensity r g b */
    uint64_t offset; /* the section's physical offset */
    uint64_t n;
} scan;

/* Writes one scan's compressed-vector section (records from v, or a helix when v is NULL). */
static void put_section(writer *w, scan *s, field *fs, int nf)
{
    s->offset = physical(w->logical);
    uint64_t start = w->logical;
    uint8_t h[32] = {1};
    put_u64(h + 16, physical(start + 32));
    /* the length is patched when known: the header is in a page written later or in this one */
    put(w, h, 32);
    for (int k = 0; k < nf; k++) fs[k].buf = malloc(PER_PACKET * 8 + 16);
    for (uint64_t i = 0; i < s->n;) {
        uint64_t end = i + PER_PACKET < s->n ? i + PER_PACKET : s->n;
        for (; i < end; i++) {
            double rec[10];
            if (s->v) {
                const double *p = s->v + 7 * i;
                int none = p[0] == 0 && p[1] == 0 && p[2] == 0;
                double r[10] = {
                    p[0],         p[1], p[2], p[3], (double)(i % (uint64_t)s->rows), (double)(i / (uint64_t)s->rows),
                    none ? 2 : 0, p[4], p[5], p[6]};
                memcpy(rec, r, sizeof r);
            } else {
                double t = (double)i * 1e-4;
                rec[0] = cos(t) * 10, rec[1] = sin(t) * 10, rec[2] = t * 0.01;
            }
            for (int k = 0; k < nf; k++) field_push(&fs[k], rec[k]);
        }
        put_packet(w, fs, nf, i == s->n);
    }
    for (int k = 0; k < nf; k++) free(fs[k].buf);
    uint64_t length = w->logical - start;
    /* Patch the section length: its header's page is either the one in memory or on disk. */
    uint64_t at = start + 8;
    uint8_t len8[8];
    put_u64(len8, length);
    for (int b = 0; b < 8; b++, at++) {
        uint64_t page = at / DATA;
        if (page == w->logical / DATA)
            w->page[at % DATA] = len8[b];
        else {
            uint8_t pg[PAGE];
            long pos = (long)(page * PAGE);
            if (fseek(w->fp, pos, SEEK_SET) != 0 || fread(pg, 1, PAGE, w->fp) != PAGE) die("re-read failed");
            pg[at % DATA] = len8[b];
            uint32_t c = rs_e57_crc32c(pg, DATA);
            pg[1020] = (uint8_t)(c >> 24), pg[1021] = (uint8_t)(c >> 16), pg[1022] = (uint8_t)(c >> 8),
            pg[1023] = (uint8_t)c;
            if (page == 0) memcpy(w->page0, pg, PAGE);
            if (fseek(w->fp, pos, SEEK_SET) != 0 || fwrite(pg, 1, PAGE, w->fp) != PAGE) die("rewrite failed");
            if (fseek(w->fp, 0, SEEK_END) != 0) die("seek failed");
        }
    }
}

/* The PTX scans (the lines as they are: local coordinates and the matrix). */
static int read_ptx(const char *path, scan **out)
{
    FILE *fp = fopen(path, "r");
    if (!fp) die("cannot open the PTX file");
    scan *scans = NULL;
    int n = 0;
    char *line = NULL;
    size_t cap = 0;
    double hdr[30];
    for (;;) {
        int k = 0;
        while (k < 30 && getline(&line, &cap, fp) > 0) {
            char *p = line, *end;
            for (double v = strtod(p, &end); end != p && k < 30; v = strtod(p = end, &end)) hdr[k++] = v;
        }
        if (k == 0) break;
        if (k < 30) die("truncated PTX header");
        scans = realloc(scans, (size_t)(n + 1) * sizeof *scans);
        scan *s = &scans[n++];
        memset(s, 0, sizeof *s);
        s->cols = (int)hdr[0], s->rows = (int)hdr[1];
        memcpy(s->T, hdr + 14, sizeof s->T);
        s->n = (uint64_t)s->cols * (uint64_t)s->rows;
        s->v = calloc(s->n * 7, sizeof *s->v);
        for (uint64_t i = 0; i < s->n; i++) {
            if (getline(&line, &cap, fp) <= 0) die("truncated PTX points");
            char *p = line, *end;
            int m = 0;
            for (double v = strtod(p, &end); end != p && m < 7; v = strtod(p = end, &end)) s->v[7 * i + m++] = v;
            if (m == 7) s->has_rgb = 1;
        }
    }
    free(line);
    fclose(fp);
    *out = scans;
    return n;
}

/* The unit quaternion (w x y z) of the PTX matrix's rotation (R[i][j] = T[4j + i]). */
static void quaternion(const double *T, double q[4])
{
    double r00 = T[0], r11 = T[5], r22 = T[10], r01 = T[4], r10 = T[1], r02 = T[8], r20 = T[2], r12 = T[9], r21 = T[6];
    double tr = r00 + r11 + r22;
    if (tr > 0) {
        double s = sqrt(tr + 1) * 2;
        q[0] = s / 4, q[1] = (r21 - r12) / s, q[2] = (r02 - r20) / s, q[3] = (r10 - r01) / s;
    } else if (r00 > r11 && r00 > r22) {
        double s = sqrt(1 + r00 - r11 - r22) * 2;
        q[0] = (r21 - r12) / s, q[1] = s / 4, q[2] = (r01 + r10) / s, q[3] = (r02 + r20) / s;
    } else if (r11 > r22) {
        double s = sqrt(1 + r11 - r00 - r22) * 2;
        q[0] = (r02 - r20) / s, q[1] = (r01 + r10) / s, q[2] = s / 4, q[3] = (r12 + r21) / s;
    } else {
        double s = sqrt(1 + r22 - r00 - r11) * 2;
        q[0] = (r10 - r01) / s, q[1] = (r02 + r20) / s, q[2] = (r12 + r21) / s, q[3] = s / 4;
    }
}

static void xml_pose(FILE *x, const double q[4], const double t[3])
{
    fprintf(
        x,
        "<pose type=\"Structure\"><rotation type=\"Structure\"><w type=\"Float\">%.17g</w><x type=\"Float\">%.17g</x>"
        "<y type=\"Float\">%.17g</y><z type=\"Float\">%.17g</z></rotation><translation type=\"Structure\">"
        "<x type=\"Float\">%.17g</x><y type=\"Float\">%.17g</y><z type=\"Float\">%.17g</z></translation></pose>\n",
        q[0], q[1], q[2], q[3], t[0], t[1], t[2]);
}

static void xml_scan(FILE *x, const scan *s, int i)
{
    fprintf(x,
            "<vectorChild type=\"Structure\"><guid type=\"String\"><![CDATA[{e57write-scan-%d}]]></guid>"
            "<name type=\"String\"><![CDATA[scan %d]]></name>\n",
            i, i);
    if (s->v) {
        double q[4], t[3] = {s->T[12], s->T[13], s->T[14]};
        quaternion(s->T, q);
        xml_pose(x, q, t);
        fprintf(x,
                "<indexBounds type=\"Structure\"><rowMinimum type=\"Integer\">0</rowMinimum><rowMaximum "
                "type=\"Integer\">%d</rowMaximum><columnMinimum type=\"Integer\">0</columnMinimum><columnMaximum "
                "type=\"Integer\">%d</columnMaximum></indexBounds>\n<intensityLimits type=\"Structure\">"
                "<intensityMinimum type=\"Float\">0</intensityMinimum><intensityMaximum type=\"Float\">1"
                "</intensityMaximum></intensityLimits>\n",
                s->rows - 1, s->cols - 1);
    }
    fprintf(x,
            "<points type=\"CompressedVector\" fileOffset=\"%llu\" recordCount=\"%llu\"><prototype "
            "type=\"Structure\"><cartesianX type=\"Float\"/><cartesianY type=\"Float\"/><cartesianZ type=\"Float\"/>\n",
            (unsigned long long)s->offset, (unsigned long long)s->n);
    if (s->v) {
        fprintf(x,
                "<intensity type=\"Float\"/><rowIndex type=\"Integer\" minimum=\"0\" maximum=\"%d\"/>"
                "<columnIndex type=\"Integer\" minimum=\"0\" maximum=\"%d\"/>"
                "<cartesianInvalidState type=\"Integer\" minimum=\"0\" maximum=\"2\"/>\n",
                s->rows - 1, s->cols - 1);
        if (s->has_rgb)
            fprintf(x,
                    "<colorRed type=\"Integer\" minimum=\"0\" maximum=\"255\"/><colorGreen type=\"Integer\" "
                    "minimum=\"0\" maximum=\"255\"/><colorBlue type=\"Integer\" minimum=\"0\" maximum=\"255\"/>\n");
    }
    fprintf(x, "</prototype><codecs type=\"Vector\" allowHeterogeneousChildren=\"1\"/></points></vectorChild>\n");
}

static int bits_for(uint64_t range)
{
    int b = 0;
    while (range) b++, range >>= 1;
    return b;
}

static void write_scan(writer *w, scan *s)
{
    field fs[10] = {{.xml = "x", .bits = 64, .is_float = 1},
                    {.xml = "y", .bits = 64, .is_float = 1},
                    {.xml = "z", .bits = 64, .is_float = 1}};
    int nf = 3;
    if (s->v) {
        fs[3] = (field){.xml = "intensity", .bits = 64, .is_float = 1};
        fs[4] = (field){.xml = "row", .bits = bits_for((uint64_t)s->rows - 1), .is_float = 0};
        fs[5] = (field){.xml = "col", .bits = bits_for((uint64_t)s->cols - 1), .is_float = 0};
        fs[6] = (field){.xml = "invalid", .bits = 2, .is_float = 0};
        nf = 7;
        for (int k = 0; k < 3 && s->has_rgb; k++) fs[nf++] = (field){.xml = "rgb", .bits = 8, .is_float = 0};
    }
    put_section(w, s, fs, nf);
}

/* The image's blob section; returns its physical offset. */
static uint64_t write_blob(writer *w, const uint8_t *data, size_t n)
{
    uint64_t off = physical(w->logical);
    uint8_t h[16] = {0};
    put_u64(h + 8, 16 + n);
    put(w, h, 16);
    put(w, data, n);
    return off;
}

typedef struct image_opt {
    const char *path, *name;
    double pose[7];
    int pinhole;         /* 0: spherical (the full sphere) */
    double pinhole_p[5]; /* focal length, pixel width, pixel height (m), principal point x, y (px) */
    int width, height, png;
    uint64_t offset;
    size_t length;
} image_opt;

static void embed_image(writer *w, image_opt *im)
{
    FILE *fp = fopen(im->path, "rb");
    if (!fp) die("cannot open the image");
    fseek(fp, 0, SEEK_END);
    size_t n = (size_t)ftell(fp);
    rewind(fp);
    uint8_t *d = malloc(n);
    if (fread(d, 1, n, fp) != n) die("cannot read the image");
    fclose(fp);
    im->png = n > 24 && memcmp(d, "\x89PNG", 4) == 0;
    if (im->png) {
        im->width = d[16] << 24 | d[17] << 16 | d[18] << 8 | d[19];
        im->height = d[20] << 24 | d[21] << 16 | d[22] << 8 | d[23];
    } else {
        /* JPEG: the first SOFn marker's height and width */
        for (size_t i = 2; i + 9 < n; i++)
            if (d[i] == 0xff && d[i + 1] >= 0xc0 && d[i + 1] <= 0xc3) {
                im->height = d[i + 5] << 8 | d[i + 6];
                im->width = d[i + 7] << 8 | d[i + 8];
                break;
            }
    }
    if (im->width <= 0 || im->height <= 0) die("the image is neither a PNG nor a JPEG with a size");
    im->length = n;
    im->offset = write_blob(w, d, n);
    free(d);
}

static void xml_image(FILE *x, const image_opt *im, int i)
{
    fprintf(x,
            "<vectorChild type=\"Structure\"><guid type=\"String\"><![CDATA[{e57write-image-%d}]]></guid>"
            "<name type=\"String\"><![CDATA[%s]]></name>"
            "<associatedData3DGuid type=\"String\"><![CDATA[{e57write-scan-0}]]></associatedData3DGuid>\n",
            i, im->name);
    xml_pose(x, im->pose, im->pose + 4);
    const char *rep = im->pinhole ? "pinholeRepresentation" : "sphericalRepresentation";
    fprintf(x,
            "<%s type=\"Structure\"><%s type=\"Blob\" fileOffset=\"%llu\" length=\"%zu\"/>"
            "<imageWidth type=\"Integer\">%d</imageWidth><imageHeight type=\"Integer\">%d</imageHeight>",
            rep, im->png ? "pngImage" : "jpegImage", (unsigned long long)im->offset, im->length, im->width, im->height);
    if (im->pinhole)
        fprintf(x,
                "<focalLength type=\"Float\">%.17g</focalLength><pixelWidth type=\"Float\">%.17g</pixelWidth>"
                "<pixelHeight type=\"Float\">%.17g</pixelHeight><principalPointX type=\"Float\">%.17g"
                "</principalPointX><principalPointY type=\"Float\">%.17g</principalPointY>",
                im->pinhole_p[0], im->pinhole_p[1], im->pinhole_p[2], im->pinhole_p[3], im->pinhole_p[4]);
    else
        fprintf(x, "<pixelWidth type=\"Float\">%.17g</pixelWidth><pixelHeight type=\"Float\">%.17g</pixelHeight>",
                2 * PI / im->width, PI / im->height);
    fprintf(x, "</%s></vectorChild>\n", rep);
}

/* The XML, then the header into page 0. */
static void finish(writer *w, scan *scans, int n, const image_opt *im, int nim)
{
    char *xml;
    size_t xlen;
    FILE *x = open_memstream(&xml, &xlen);
    fprintf(x,
            "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<e57Root type=\"Structure\" "
            "xmlns=\"http://www.astm.org/COMMIT/E57/2010-e57-v1.0\">\n<formatName type=\"String\"><![CDATA[ASTM E57 "
            "3D Imaging Data File]]></formatName><guid type=\"String\"><![CDATA[{e57write}]]></guid>"
            "<versionMajor type=\"Integer\">1</versionMajor><versionMinor type=\"Integer\">0</versionMinor>\n"
            "<data3D type=\"Vector\" allowHeterogeneousChildren=\"1\">\n");
    for (int i = 0; i < n; i++) xml_scan(x, &scans[i], i);
    fprintf(x, "</data3D>\n");
    if (nim) fprintf(x, "<images2D type=\"Vector\" allowHeterogeneousChildren=\"1\">\n");
    for (int i = 0; i < nim; i++) xml_image(x, &im[i], i);
    if (nim) fprintf(x, "</images2D>\n");
    fprintf(x, "</e57Root>\n");
    fclose(x);
    uint64_t xoff = physical(w->logical);
    put(w, xml, xlen);
    free(xml);
    if (w->fill) flush_page(w);
    uint8_t *h = w->page0;
    memcpy(h, "ASTM-E57", 8);
    h[8] = 1, h[9] = h[10] = h[11] = 0, h[12] = h[13] = h[14] = h[15] = 0;
    put_u64(h + 16, w->pages * PAGE);
    put_u64(h + 24, xoff);
    put_u64(h + 32, xlen);
    put_u64(h + 40, PAGE);
    uint32_t c = rs_e57_crc32c(h, DATA);
    h[1020] = (uint8_t)(c >> 24), h[1021] = (uint8_t)(c >> 16), h[1022] = (uint8_t)(c >> 8), h[1023] = (uint8_t)c;
    if (fseek(w->fp, 0, SEEK_SET) != 0 || fwrite(h, 1, PAGE, w->fp) != PAGE) die("header write failed");
}

#define MAX_IMAGES 16

/* An image option (applies to the last --image). */
static void image_option(image_opt *im, const char *opt, const char *arg)
{
    if (strcmp(opt, "--image-name") == 0)
        im->name = arg;
    else if (strcmp(opt, "--image-pose") == 0) {
        if (sscanf(arg, "%lf %lf %lf %lf %lf %lf %lf", &im->pose[0], &im->pose[1], &im->pose[2], &im->pose[3],
                   &im->pose[4], &im->pose[5], &im->pose[6]) != 7)
            die("--image-pose: expected \"w x y z tx ty tz\"");
    } else if (strcmp(opt, "--pinhole") == 0) {
        im->pinhole = 1;
        if (sscanf(arg, "%lf %lf %lf %lf %lf", &im->pinhole_p[0], &im->pinhole_p[1], &im->pinhole_p[2],
                   &im->pinhole_p[3], &im->pinhole_p[4]) != 5)
            die("--pinhole: expected \"focal_m pixel_width_m pixel_height_m principal_x_px principal_y_px\"");
    } else
        die("unknown option");
}

int main(int argc, char **argv)
{
    static image_opt im[MAX_IMAGES];
    int nim = 0;
    long long synthetic = -1;
    int a = 1;
    for (; a + 1 < argc && strncmp(argv[a], "--", 2) == 0; a += 2) {
        if (strcmp(argv[a], "--image") == 0) {
            if (nim == MAX_IMAGES) die("at most 16 images");
            im[nim++] = (image_opt){.path = argv[a + 1], .name = "panorama", .pose = {1, 0, 0, 0, 0, 0, 0}};
        } else if (strcmp(argv[a], "--synthetic") == 0)
            synthetic = atoll(argv[a + 1]);
        else if (nim > 0)
            image_option(&im[nim - 1], argv[a], argv[a + 1]);
        else
            die("unknown option (image options follow their --image)");
    }
    if (argc - a != (synthetic >= 0 ? 1 : 2))
        die("usage: e57write [--image F [--image-pose \"w x y z tx ty tz\"] [--image-name N] [--pinhole \"f pw ph "
            "cx cy\"]]... in.ptx out.e57 | e57write --synthetic N out.e57");
    scan one = {.n = (uint64_t)(synthetic > 0 ? synthetic : 0)}, *scans = &one;
    int n = synthetic >= 0 ? 1 : read_ptx(argv[a], &scans);
    writer w = {.fp = fopen(argv[argc - 1], "w+b")};
    if (!w.fp) die("cannot create the output");
    static const uint8_t header[48];
    put(&w, header, sizeof header);
    for (int i = 0; i < n; i++) write_scan(&w, &scans[i]);
    for (int i = 0; i < nim; i++) embed_image(&w, &im[i]);
    finish(&w, scans, n, im, nim);
    if (fclose(w.fp) != 0) die("close failed");
    for (int i = 0; i < n && synthetic < 0; i++) free(scans[i].v);
    if (synthetic < 0) free(scans);
    return 0;
}

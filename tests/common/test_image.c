/* test_image: EXR, Radiance .hdr and PNG reading and writing (common/image*.c): round trips,
 * channel matching, windows, tiles, and bad input that must fail cleanly. */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include <dirent.h>
#include <omp.h>
#include <openexr.h>
#include <stb_image.h> /* both implemented in common/image_stb.c */
#include <stb_image_write.h>

#include "common/fileio.h"
#include "common/image.h"

static const char *tmp;

static int setup(void **state)
{
    tmp = rs_test_tmpdir("image");
    return 0;
}

static int teardown(void **state)
{
    rs_test_rmtree(tmp);
    return 0;
}

/* The formatted error names the file and contains the expected words. */
static void assert_err_mentions(const rs_err *err, const char *file, const char *what)
{
    char buf[2048];
    rs_err_format(err, buf, sizeof buf);
    if (!strstr(buf, file) || (what && !strstr(buf, what)))
        fail_msg("error '%s' should name '%s' and say '%s'", buf, file, what ? what : "");
}

static void write_bytes(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(data, 1, n, f), n);
    assert_int_equal(fclose(f), 0);
}

static unsigned char *slurp(const char *path, size_t *n)
{
    char *data = NULL;
    rs_err err = {0};
    assert_int_equal(rs_read_file(path, &data, n, &err), 0);
    return (unsigned char *)data;
}

/* No "<name>.tmp.<pid>" left over in the folder. */
static void assert_no_temporaries(const char *dir)
{
    DIR *d = opendir(dir);
    assert_non_null(d);
    struct dirent *e;
    while ((e = readdir(d)) != NULL)
        if (strstr(e->d_name, ".tmp.")) fail_msg("temporary file left: %s", e->d_name);
    closedir(d);
}

static float test_value(int x, int y, int c)
{
    return (float)(c + 1) * 0.25f + (float)x * 1.5f - (float)y * 3.0f;
}

static void test_srgb(void **state)
{
    assert_float_equal(rs_srgb_to_linear(0.0f), 0.0f, 1e-7);
    assert_float_equal(rs_srgb_to_linear(1.0f), 1.0f, 1e-6);
    assert_float_equal(rs_srgb_to_linear(128.0f / 255.0f), 0.2158f, 1e-4);
    assert_float_equal(rs_srgb_to_linear(0.04f), 0.04f / 12.92f, 1e-7);
    for (int i = 0; i <= 255; i++) {
        float v = (float)i / 255.0f;
        assert_float_equal(rs_linear_to_srgb(rs_srgb_to_linear(v)), v, 1e-5);
    }
}

static void test_new_rejects_bad_sizes(void **state)
{
    assert_null(rs_image_new(0, 5, 3));
    assert_null(rs_image_new(5, -1, 3));
    assert_null(rs_image_new(65537, 5, 1));
    assert_null(rs_image_new(5, 5, 0));
    rs_image *img = rs_image_new(3, 2, 3);
    assert_non_null(img);
    for (int i = 0; i < 18; i++) assert_true(img->data[i] == 0.0f);
    assert_ptr_equal(rs_image_px(img, 2, 1), img->data + 15);
    rs_image_free(img);
    rs_image_free(NULL);
}

/* Float and half, one and three channels; values differ per channel so that a mix-up of
 * the file's alphabetical channel order (B, G, R) would show. */
static void test_exr_round_trip(void **state)
{
    static const char *rgb[] = {"R", "G", "B"};
    static const char *one[] = {"depth"};
    for (int half = 0; half <= 1; half++) {
        for (int nc = 1; nc <= 3; nc += 2) {
            rs_image *img = rs_image_new(7, 5, nc);
            assert_non_null(img);
            for (int y = 0; y < 5; y++)
                for (int x = 0; x < 7; x++)
                    for (int c = 0; c < nc; c++) rs_image_px(img, x, y)[c] = test_value(x, y, c) * 1.001f;
            rs_image_px(img, 3, 2)[0] = 12345.0f;
            rs_image_px(img, 4, 2)[0] = 1e5f; /* beyond half's range: Inf in half files */
            const char *path = rs_test_path(tmp, half ? "half.exr" : "float.exr");
            rs_err err = {0};
            const char *const *names = nc == 3 ? rgb : one;
            assert_int_equal(rs_image_write_exr(img, path, names, half, NULL, &err), 0);
            rs_image *back = rs_image_read(path, &err);
            if (!back) fail_msg("%s", err.msg);
            assert_int_equal(back->width, 7);
            assert_int_equal(back->height, 5);
            assert_int_equal(back->channels, nc);
            for (size_t i = 0; i < (size_t)7 * 5 * (size_t)nc; i++) {
                if (half && img->data[i] > 65504.0f)
                    assert_true(isinf(back->data[i]));
                else if (half)
                    assert_float_equal(back->data[i], img->data[i], 1e-3 * fabsf(img->data[i]) + 1e-6);
                else
                    assert_true(back->data[i] == img->data[i]);
            }
            rs_image_free(back);
            rs_image_free(img);
        }
    }
    assert_no_temporaries(tmp);
}

static void ignore_exr_error(exr_const_context_t c, exr_result_t code, const char *msg) {}

static void test_exr_note_and_determinism(void **state)
{
    static const char *rgb[] = {"R", "G", "B"};
    rs_image *img = rs_image_new(16, 8, 3);
    for (size_t i = 0; i < 16 * 8 * 3; i++) img->data[i] = (float)i * 0.01f;
    const char *a = rs_test_path(tmp, "a.exr"), *b = rs_test_path(tmp, "b.exr");
    const char *note = "rhoscan-render 0.1.0 config=abc";
    rs_err err = {0};
    assert_int_equal(rs_image_write_exr(img, a, rgb, 1, note, &err), 0);
    assert_int_equal(rs_image_write_exr(img, b, rgb, 1, note, &err), 0);

    size_t na, nb;
    unsigned char *da = slurp(a, &na), *db = slurp(b, &nb);
    assert_int_equal(na, nb);
    assert_memory_equal(da, db, na);
    free(da);
    free(db);

    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = ignore_exr_error;
    exr_context_t ctx = NULL;
    assert_int_equal(exr_start_read(&ctx, a, &init), EXR_ERR_SUCCESS);
    int32_t len = 0;
    const char *s = NULL;
    assert_int_equal(exr_attr_get_string(ctx, 0, "rhoscan", &len, &s), EXR_ERR_SUCCESS);
    assert_int_equal(len, (int32_t)strlen(note));
    assert_memory_equal(s, note, strlen(note));
    exr_compression_t comp;
    assert_int_equal(exr_get_compression(ctx, 0, &comp), EXR_ERR_SUCCESS);
    assert_int_equal(comp, EXR_COMPRESSION_ZIP);
    const exr_attr_chlist_t *chl = NULL;
    assert_int_equal(exr_get_channels(ctx, 0, &chl), EXR_ERR_SUCCESS);
    assert_int_equal(chl->num_channels, 3);
    assert_int_equal(chl->entries[0].pixel_type, EXR_PIXEL_HALF);
    exr_finish(&ctx);
    rs_image_free(img);
}

/* Writes an EXR with the core API directly, for layouts rs_image_write_exr never makes:
 * data windows apart from the display window, tiles, UINT channels, extra channels.
 * Pixel (x, y) of channel k (file coordinates) holds exr_value(k, x, y). */
typedef struct {
    const char *name;
    exr_pixel_type_t type;
} tchan;

static exr_attr_box2i_t box(int x0, int y0, int x1, int y1)
{
    exr_attr_box2i_t b;
    b.min.x = x0, b.min.y = y0, b.max.x = x1, b.max.y = y1;
    return b;
}

static uint32_t exr_value(int k, int x, int y)
{
    return (uint32_t)(1000 * (k + 1) + 40 * (y + 20) + (x + 20));
}

static void write_core(const char *path, int tiled, exr_attr_box2i_t disp, exr_attr_box2i_t dw, const tchan *ch,
                       int nch, exr_compression_t comp)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = ignore_exr_error;
    exr_context_t ctx = NULL;
    int part = 0;
    exr_attr_v2f_t centre = {.x = 0, .y = 0};
    assert_int_equal(exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init), 0);
    exr_storage_t storage = tiled ? EXR_STORAGE_TILED : EXR_STORAGE_SCANLINE;
    assert_int_equal(exr_add_part(ctx, "p", storage, &part), 0);
    assert_int_equal(
        exr_initialize_required_attr(ctx, part, &disp, &dw, 1.0f, &centre, 1.0f, EXR_LINEORDER_INCREASING_Y, comp), 0);
    for (int k = 0; k < nch; k++)
        assert_int_equal(exr_add_channel(ctx, part, ch[k].name, ch[k].type, EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1), 0);
    if (tiled) assert_int_equal(exr_set_tile_descriptor(ctx, part, 4, 4, EXR_TILE_ONE_LEVEL, EXR_TILE_ROUND_DOWN), 0);
    assert_int_equal(exr_write_header(ctx), 0);
    int w = dw.max.x - dw.min.x + 1, h = dw.max.y - dw.min.y + 1;
    int32_t lines = 0;
    if (!tiled) assert_int_equal(exr_get_scanlines_per_chunk(ctx, part, &lines), 0);
    int ntx = tiled ? (w + 3) / 4 : 1, nty = tiled ? (h + 3) / 4 : (h + lines - 1) / lines;
    for (int ty = 0; ty < nty; ty++) {
        for (int tx = 0; tx < ntx; tx++) {
            exr_chunk_info_t ci;
            int x0 = dw.min.x + tx * 4, y0 = tiled ? dw.min.y + ty * 4 : dw.min.y + ty * lines;
            if (tiled)
                assert_int_equal(exr_write_tile_chunk_info(ctx, part, tx, ty, 0, 0, &ci), 0);
            else
                assert_int_equal(exr_write_scanline_chunk_info(ctx, part, y0, &ci), 0);
            exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
            assert_int_equal(exr_encoding_initialize(ctx, part, &ci, &enc), 0);
            union {
                uint32_t u;
                float f;
            } *buf = calloc((size_t)ci.width * ci.height * nch, 4);
            for (int c = 0; c < enc.channel_count; c++) {
                int k = 0;
                while (strcmp(ch[k].name, enc.channels[c].channel_name) != 0) k++;
                for (int r = 0; r < ci.height; r++)
                    for (int q = 0; q < ci.width; q++) {
                        uint32_t v = exr_value(k, x0 + q, y0 + r);
                        size_t i = (size_t)k * ci.width * ci.height + (size_t)r * ci.width + q;
                        if (ch[k].type == EXR_PIXEL_UINT)
                            buf[i].u = v;
                        else
                            buf[i].f = (float)v;
                    }
                enc.channels[c].encode_from_ptr = (const uint8_t *)(buf + (size_t)k * ci.width * ci.height);
                enc.channels[c].user_pixel_stride = 4;
                enc.channels[c].user_line_stride = 4 * ci.width;
                enc.channels[c].user_bytes_per_element = 4;
                enc.channels[c].user_data_type =
                    (uint16_t)(ch[k].type == EXR_PIXEL_UINT ? EXR_PIXEL_UINT : EXR_PIXEL_FLOAT);
            }
            assert_int_equal(exr_encoding_choose_default_routines(ctx, part, &enc), 0);
            assert_int_equal(exr_encoding_run(ctx, part, &enc), 0);
            exr_encoding_destroy(ctx, &enc);
            free(buf);
        }
    }
    assert_int_equal(exr_finish(&ctx), 0);
}

/* The result covers the display window; outside the data window it is 0; A is dropped. */
static void check_windows(const char *path, exr_attr_box2i_t disp, exr_attr_box2i_t dw, int nc)
{
    rs_err err = {0};
    rs_image *img = rs_image_read(path, &err);
    if (!img) fail_msg("%s", err.msg);
    assert_int_equal(img->width, disp.max.x - disp.min.x + 1);
    assert_int_equal(img->height, disp.max.y - disp.min.y + 1);
    assert_int_equal(img->channels, nc);
    for (int y = disp.min.y; y <= disp.max.y; y++)
        for (int x = disp.min.x; x <= disp.max.x; x++) {
            int inside = x >= dw.min.x && x <= dw.max.x && y >= dw.min.y && y <= dw.max.y;
            const float *px = rs_image_px(img, x - disp.min.x, y - disp.min.y);
            for (int k = 0; k < nc; k++) {
                /* Channels were declared R, G, B, A: k is also the declaration index. */
                float want = inside ? (float)exr_value(k, x, y) : 0.0f;
                if (px[k] != want) fail_msg("%s (%d,%d)[%d] = %g, want %g", path, x, y, k, px[k], want);
            }
        }
    rs_image_free(img);
}

static void test_exr_windows_tiles_types(void **state)
{
    const tchan rgba[] = {
        {"R", EXR_PIXEL_FLOAT}, {"G", EXR_PIXEL_FLOAT}, {"B", EXR_PIXEL_FLOAT}, {"A", EXR_PIXEL_FLOAT}};
    const tchan depth[] = {{"depth", EXR_PIXEL_UINT}};
    exr_attr_box2i_t disp = box(0, 0, 7, 5);
    exr_attr_box2i_t dw = box(2, 1, 5, 3);
    const char *p = rs_test_path(tmp, "window.exr");
    write_core(p, 0, disp, dw, rgba, 4, EXR_COMPRESSION_ZIP);
    check_windows(p, disp, dw, 3);

    /* Data window larger than the display window on one side (overscan): cropped. */
    exr_attr_box2i_t over = box(-2, -1, 9, 4);
    p = rs_test_path(tmp, "overscan.exr");
    write_core(p, 0, disp, over, rgba, 3, EXR_COMPRESSION_PIZ);
    check_windows(p, disp, over, 3);

    /* Tiled, negative origin, partial edge tiles, a single UINT channel with any name.
     * (Not ZIP: OpenEXR 3.1.5's core writer corrupts UINT chunks that ZIP cannot shrink.) */
    exr_attr_box2i_t tdisp = box(-3, 2, 6, 8);
    p = rs_test_path(tmp, "tiled.exr");
    write_core(p, 1, tdisp, tdisp, depth, 1, EXR_COMPRESSION_PIZ);
    check_windows(p, tdisp, tdisp, 1);
    p = rs_test_path(tmp, "tiled_rgba.exr");
    write_core(p, 1, tdisp, tdisp, rgba, 4, EXR_COMPRESSION_ZIP);
    check_windows(p, tdisp, tdisp, 3);
    p = rs_test_path(tmp, "tiled_none.exr");
    write_core(p, 1, tdisp, tdisp, rgba, 3, EXR_COMPRESSION_NONE);
    check_windows(p, tdisp, tdisp, 3);

    /* Y with A is luminance. */
    const tchan ya[] = {{"Y", EXR_PIXEL_FLOAT}, {"A", EXR_PIXEL_HALF}};
    p = rs_test_path(tmp, "ya.exr");
    write_core(p, 0, disp, disp, ya, 2, EXR_COMPRESSION_RLE);
    check_windows(p, disp, disp, 1);

    /* The other compressions the C library writes and reads. */
    const exr_compression_t others[] = {EXR_COMPRESSION_ZIPS, EXR_COMPRESSION_PXR24, EXR_COMPRESSION_B44,
                                        EXR_COMPRESSION_B44A};
    for (int i = 0; i < 4; i++) {
        p = rs_test_path(tmp, "other.exr");
        write_core(p, 0, disp, dw, rgba, 3, others[i]);
        check_windows(p, disp, dw, 3);
    }

    /* Disjoint windows have nothing to show. */
    exr_attr_box2i_t away = box(20, 20, 23, 23);
    p = rs_test_path(tmp, "away.exr");
    write_core(p, 0, disp, away, rgba, 3, EXR_COMPRESSION_ZIP);
    rs_err err = {0};
    assert_null(rs_image_read(p, &err));
    assert_err_mentions(&err, p, "display window");
}

static void test_exr_channel_errors(void **state)
{
    static const char *xz[] = {"X", "Z"};
    rs_image *img = rs_image_new(4, 4, 2);
    const char *p = rs_test_path(tmp, "xz.exr");
    rs_err err = {0};
    assert_int_equal(rs_image_write_exr(img, p, xz, 0, NULL, &err), 0);
    assert_null(rs_image_read(p, &err));
    assert_err_mentions(&err, p, "{X,Z}");
    assert_err_mentions(&err, p, "expected R,G,B");
    rs_image_free(img);

    /* R and G but no B. */
    const tchan rg[] = {{"R", EXR_PIXEL_HALF}, {"G", EXR_PIXEL_HALF}};
    exr_attr_box2i_t win = box(0, 0, 3, 3);
    p = rs_test_path(tmp, "rg.exr");
    write_core(p, 0, win, win, rg, 2, EXR_COMPRESSION_ZIP);
    assert_null(rs_image_read(p, &err));
    assert_err_mentions(&err, p, "{G,R}");
}

static void test_exr_write_failure(void **state)
{
    static const char *y[] = {"Y"};
    rs_image *img = rs_image_new(4, 4, 1);
    const char *p = rs_test_path(tmp, "missing-folder/out.exr");
    rs_err err = {0};
    assert_int_equal(rs_image_write_exr(img, p, y, 0, NULL, &err), -1);
    assert_err_mentions(&err, p, NULL);
    rs_image_free(img);
}

static void collect(void *ctx, void *data, int size)
{
    void **b = ctx; /* b[0] = buffer, b[1] = length as size_t* */
    size_t *n = b[1];
    b[0] = realloc(b[0], *n + (size_t)size);
    memcpy((char *)b[0] + *n, data, (size_t)size);
    *n += (size_t)size;
}

static void test_hdr_from_memory(void **state)
{
    float px[4 * 3 * 3];
    for (int i = 0; i < 36; i++) px[i] = 0.001f * powf(3.0f, (float)(i % 18)); /* up to ~1.3e5 */
    size_t n = 0;
    void *b[2] = {NULL, &n};
    assert_true(stbi_write_hdr_to_func(collect, b, 4, 3, 3, px));
    rs_err err = {0};
    rs_image *img = rs_image_read_mem(b[0], n, "sky.hdr", &err);
    if (!img) fail_msg("%s", err.msg);
    assert_int_equal(img->width, 4);
    assert_int_equal(img->height, 3);
    assert_int_equal(img->channels, 3);
    /* RGBE shares one exponent per pixel: 8 bits of mantissa relative to the largest. */
    for (int i = 0; i < 36; i++) {
        const float *pix = px + i / 3 * 3;
        assert_float_equal(img->data[i], px[i], fmaxf(fmaxf(pix[0], pix[1]), pix[2]) / 128.0f);
    }
    rs_image_free(img);

    /* The same bytes through a file; a cut file fails and names the file. */
    const char *p = rs_test_path(tmp, "sky.hdr");
    write_bytes(p, b[0], n);
    img = rs_image_read(p, &err);
    assert_non_null(img);
    rs_image_free(img);
    write_bytes(p, b[0], n / 2);
    assert_null(rs_image_read(p, &err));
    assert_err_mentions(&err, p, "Radiance");
    /* 4 pixels wide is stored flat (no runs): one pixel short must fail, not pad with 0. */
    assert_null(rs_image_read_mem(b[0], n - 4, "flat.hdr", &err));
    assert_err_mentions(&err, "flat.hdr", "truncated");
    free(b[0]);
}

/* Found by fuzzing (tests/fuzz/corpus/image/hang-nul-header.hdr): stb ends the header at a
 * line that starts with a NUL byte, not only at an empty line; the run-length guard must
 * find the same scanlines, or stb spins forever on the zero count that follows. alarm()
 * turns a regression into a failure instead of a hang. */
static void test_hdr_nul_header_zero_run(void **state)
{
    static const unsigned char bad[] = "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\0\n-Y 1 +X 8\n"
                                       "\x02\x02\x00\x08\x84\x05\x00\x00";
    rs_err err = {0};
    alarm(20);
    assert_null(rs_image_read_mem(bad, sizeof bad - 1, "nul.hdr", &err));
    assert_err_mentions(&err, "nul.hdr", "run-length data");
    /* The corpus file that found it, when the source tree is at hand. */
    const char *src = getenv("RHOSCAN_SOURCE_DIR");
    if (src) {
        char path[4096];
        snprintf(path, sizeof path, "%s/tests/fuzz/corpus/image/hang-nul-header.hdr", src);
        assert_null(rs_image_read(path, &err));
        assert_err_mentions(&err, path, "Radiance .hdr");
    }
    alarm(0);
}

/* Found by fuzzing (tests/fuzz/corpus/image/segv-exr-subsampled-alpha.exr): an EXR whose A
 * channel is subsampled 1 x 2 crashed OpenEXR's decoder though A is never read; refused now. */
static void test_exr_subsampled_channel(void **state)
{
    (void)state;
    char path[4096];
    snprintf(path, sizeof path, "%s/tests/fuzz/corpus/image/segv-exr-subsampled-alpha.exr", rs_test_source_dir());
    rs_err err = {0};
    assert_null(rs_image_read(path, &err));
    assert_err_mentions(&err, path, "channel A is subsampled (1 x 2)");
}

/* Found by fuzzing (tests/fuzz/corpus/image/oom-png-huge-chunk.png): a PNG chunk that claims
 * 1 GB in a 150-byte file made stb allocate that much before reading it; now refused by size. */
static void test_png_chunk_past_end(void **state)
{
    const char *src = getenv("RHOSCAN_SOURCE_DIR");
    if (!src) skip();
    char path[4096];
    snprintf(path, sizeof path, "%s/tests/fuzz/corpus/image/oom-png-huge-chunk.png", src);
    rs_err err = {0};
    assert_null(rs_image_read(path, &err));
    assert_err_mentions(&err, path, "runs past the end");
    /* A good PNG cut inside its last data chunk fails the same way. */
    rs_image *img = rs_image_new(5, 4, 3);
    for (size_t i = 0; i < 5 * 4 * 3; i++) img->data[i] = (float)(i % 7) / 7.0f;
    const char *png = rs_test_path(tmp, "cut.png");
    assert_int_equal(rs_image_write_png(img, png, 1.0f, &err), 0);
    rs_image_free(img);
    size_t n;
    unsigned char *good = slurp(png, &n);
    assert_null(rs_image_read_mem(good, n - 13, "cut.png", &err)); /* IEND (12) and a CRC byte */
    assert_err_mentions(&err, "cut.png", "runs past the end");
    free(good);
}

static void test_png_linearised(void **state)
{
    unsigned char rgb[2 * 2 * 3], grey[3 * 1 * 2];
    memset(rgb, 128, sizeof rgb);
    rgb[0] = 255, rgb[1] = 0;
    for (int i = 0; i < 6; i += 2) grey[i] = 128, grey[i + 1] = 7; /* grey + alpha */
    size_t n = 0;
    void *b[2] = {NULL, &n};
    assert_true(stbi_write_png_to_func(collect, b, 2, 2, 3, rgb, 6));
    rs_err err = {0};
    rs_image *img = rs_image_read_mem(b[0], n, "rgb.png", &err);
    if (!img) fail_msg("%s", err.msg);
    assert_int_equal(img->channels, 3);
    assert_float_equal(img->data[0], 1.0f, 1e-6);
    assert_float_equal(img->data[1], 0.0f, 1e-9);
    for (int i = 2; i < 12; i++) assert_float_equal(img->data[i], 0.2158f, 1e-4);
    rs_image_free(img);
    free(b[0]);

    n = 0;
    b[0] = NULL;
    assert_true(stbi_write_png_to_func(collect, b, 3, 1, 2, grey, 6));
    img = rs_image_read_mem(b[0], n, "grey.png", &err);
    assert_non_null(img);
    assert_int_equal(img->channels, 1);
    assert_int_equal(img->width, 3);
    for (int i = 0; i < 3; i++) assert_float_equal(img->data[i], 0.2158f, 1e-4);
    rs_image_free(img);
    free(b[0]);
}

/* An 8 x 8 JPEG of grey 128 made by stb_image_write (quality 95). Embedded because that
 * writer shifts signed ints past their range, which the sanitizer build stops on. */
static const unsigned char grey8_jpg[] =
    "\xff\xd8\xff\xe0\x00\x10\x4a\x46\x49\x46\x00\x01\x01\x00\x00\x01\x00\x01\x00\x00\xff\xdb"
    "\x00\x84\x00\x02\x01\x01\x01\x01\x01\x02\x01\x01\x01\x02\x02\x02\x02\x02\x04\x03\x02\x02"
    "\x02\x02\x05\x04\x04\x03\x04\x06\x05\x06\x06\x06\x05\x06\x06\x06\x07\x09\x08\x06\x07\x09"
    "\x07\x06\x06\x08\x0b\x08\x09\x0a\x0a\x0a\x0a\x0a\x06\x08\x0b\x0c\x0b\x0a\x0c\x09\x0a\x0a"
    "\x0a\x01\x02\x02\x02\x02\x02\x02\x05\x03\x03\x05\x0a\x07\x06\x07\x0a\x0a\x0a\x0a\x0a\x0a"
    "\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a"
    "\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a\x0a"
    "\xff\xc0\x00\x11\x08\x00\x08\x00\x08\x03\x01\x11\x00\x02\x11\x01\x03\x11\x01\xff\xc4\x01"
    "\xa2\x00\x00\x01\x05\x01\x01\x01\x01\x01\x01\x00\x00\x00\x00\x00\x00\x00\x00\x01\x02\x03"
    "\x04\x05\x06\x07\x08\x09\x0a\x0b\x10\x00\x02\x01\x03\x03\x02\x04\x03\x05\x05\x04\x04\x00"
    "\x00\x01\x7d\x01\x02\x03\x00\x04\x11\x05\x12\x21\x31\x41\x06\x13\x51\x61\x07\x22\x71\x14"
    "\x32\x81\x91\xa1\x08\x23\x42\xb1\xc1\x15\x52\xd1\xf0\x24\x33\x62\x72\x82\x09\x0a\x16\x17"
    "\x18\x19\x1a\x25\x26\x27\x28\x29\x2a\x34\x35\x36\x37\x38\x39\x3a\x43\x44\x45\x46\x47\x48"
    "\x49\x4a\x53\x54\x55\x56\x57\x58\x59\x5a\x63\x64\x65\x66\x67\x68\x69\x6a\x73\x74\x75\x76"
    "\x77\x78\x79\x7a\x83\x84\x85\x86\x87\x88\x89\x8a\x92\x93\x94\x95\x96\x97\x98\x99\x9a\xa2"
    "\xa3\xa4\xa5\xa6\xa7\xa8\xa9\xaa\xb2\xb3\xb4\xb5\xb6\xb7\xb8\xb9\xba\xc2\xc3\xc4\xc5\xc6"
    "\xc7\xc8\xc9\xca\xd2\xd3\xd4\xd5\xd6\xd7\xd8\xd9\xda\xe1\xe2\xe3\xe4\xe5\xe6\xe7\xe8\xe9"
    "\xea\xf1\xf2\xf3\xf4\xf5\xf6\xf7\xf8\xf9\xfa\x01\x00\x03\x01\x01\x01\x01\x01\x01\x01\x01"
    "\x01\x00\x00\x00\x00\x00\x00\x01\x02\x03\x04\x05\x06\x07\x08\x09\x0a\x0b\x11\x00\x02\x01"
    "\x02\x04\x04\x03\x04\x07\x05\x04\x04\x00\x01\x02\x77\x00\x01\x02\x03\x11\x04\x05\x21\x31"
    "\x06\x12\x41\x51\x07\x61\x71\x13\x22\x32\x81\x08\x14\x42\x91\xa1\xb1\xc1\x09\x23\x33\x52"
    "\xf0\x15\x62\x72\xd1\x0a\x16\x24\x34\xe1\x25\xf1\x17\x18\x19\x1a\x26\x27\x28\x29\x2a\x35"
    "\x36\x37\x38\x39\x3a\x43\x44\x45\x46\x47\x48\x49\x4a\x53\x54\x55\x56\x57\x58\x59\x5a\x63"
    "\x64\x65\x66\x67\x68\x69\x6a\x73\x74\x75\x76\x77\x78\x79\x7a\x82\x83\x84\x85\x86\x87\x88"
    "\x89\x8a\x92\x93\x94\x95\x96\x97\x98\x99\x9a\xa2\xa3\xa4\xa5\xa6\xa7\xa8\xa9\xaa\xb2\xb3"
    "\xb4\xb5\xb6\xb7\xb8\xb9\xba\xc2\xc3\xc4\xc5\xc6\xc7\xc8\xc9\xca\xd2\xd3\xd4\xd5\xd6\xd7"
    "\xd8\xd9\xda\xe2\xe3\xe4\xe5\xe6\xe7\xe8\xe9\xea\xf2\xf3\xf4\xf5\xf6\xf7\xf8\xf9\xfa\xff"
    "\xda\x00\x0c\x03\x01\x00\x02\x11\x03\x11\x00\x3f\x00\x28\x03\xff\xd9";

/* JPEG: lossy, so flat grey 128 comes back within a code value. Then corruptions that
 * Debian's stb_image 2.27 mishandles and image_stb.c refuses up front. */
static void test_jpeg_and_stb_guards(void **state)
{
    unsigned char grey[16 * 16 * 3];
    memset(grey, 128, sizeof grey);
    size_t n = sizeof grey8_jpg - 1;
    unsigned char *jpg = malloc(n);
    memcpy(jpg, grey8_jpg, n);
    rs_err err = {0};
    rs_image *img = rs_image_read_mem(jpg, n, "grey.jpg", &err);
    if (!img) fail_msg("%s", err.msg);
    assert_int_equal(img->width, 8);
    assert_int_equal(img->channels, 3);
    for (int i = 0; i < 8 * 8 * 3; i++) assert_float_equal(img->data[i], 0.2158f, 0.004f);
    rs_image_free(img);

    /* The same bytes claiming 4096 x 4096 pixels (SOF0 height and width). */
    size_t sof = 0;
    for (size_t i = 2; i + 8 < n && !sof; i++)
        if (jpg[i] == 0xff && jpg[i + 1] == 0xc0) sof = i;
    assert_true(sof > 0);
    unsigned char *big = malloc(n);
    memcpy(big, jpg, n);
    big[sof + 5] = big[sof + 7] = 0x10, big[sof + 6] = big[sof + 8] = 0;
    assert_null(rs_image_read_mem(big, n, "big.jpg", &err));
    assert_err_mentions(&err, "big.jpg", "cannot come from");
    free(big);

    size_t dht = 0;
    for (size_t i = 2; i + 1 < n && !dht; i++)
        if (jpg[i] == 0xff && jpg[i + 1] == 0xc4) dht = i;
    assert_true(dht > 0);
    memset(jpg + dht + 5, 0xff, 16); /* 16 x 255 codes in the first table */
    assert_null(rs_image_read_mem(jpg, n, "dht.jpg", &err));
    assert_err_mentions(&err, "dht.jpg", "Huffman");
    free(jpg);

    n = 0;
    void *b[2] = {NULL, &n};
    assert_true(stbi_write_png_to_func(collect, b, 16, 16, 3, grey, 48));
    unsigned char *png = malloc(n + 12);
    static const unsigned char empty_idat[12] = {0, 0, 0, 0, 'I', 'D', 'A', 'T', 0x35, 0xaf, 0x06, 0x1e};
    memcpy(png, b[0], 33); /* signature and IHDR */
    memcpy(png + 33, empty_idat, 12);
    memcpy(png + 45, (unsigned char *)b[0] + 33, n - 33);
    assert_null(rs_image_read_mem(png, n + 12, "idat.png", &err));
    assert_err_mentions(&err, "idat.png", "IDAT");
    free(png);
    free(b[0]);
}

static void test_png_preview_round_trip(void **state)
{
    rs_image *img = rs_image_new(3, 2, 3);
    float vals[6] = {0.2158f * 4.0f, 8.0f, -1.0f, NAN, 0.0f, 0.5f};
    for (int i = 0; i < 18; i++) img->data[i] = vals[i % 6];
    const char *p = rs_test_path(tmp, "preview.png");
    rs_err err = {0};
    assert_int_equal(rs_image_write_png(img, p, 0.25f, &err), 0);
    rs_image *back = rs_image_read(p, &err);
    if (!back) fail_msg("%s", err.msg);
    assert_int_equal(back->channels, 3);
    float want[6] = {0.2158f, 1.0f, 0.0f, 0.0f, 0.0f, 0.125f};
    for (int i = 0; i < 18; i++) assert_float_equal(back->data[i], want[i % 6], 2e-3);
    rs_image_free(back);
    rs_image_free(img);

    rs_image *two = rs_image_new(2, 2, 2);
    assert_int_equal(rs_image_write_png(two, p, 1.0f, &err), -1);
    rs_image_free(two);
    assert_no_temporaries(tmp);
}

/* rs_image_write chooses the writer by extension (the formats' table): .exr with default
 * names, .png with a default scale of 1; a format read but not written is refused. A file
 * whose bytes match no format names the format its extension claims. */
static void test_write_by_extension(void **state)
{
    rs_image *img = rs_image_new(4, 3, 3);
    for (int i = 0; i < 4 * 3 * 3; i++) img->data[i] = 0.125f * (float)(i % 7);
    rs_err err = {0};
    const char *exr = rs_test_path(tmp, "by_ext.exr");
    assert_int_equal(rs_image_write(img, exr, NULL, &err), 0);
    rs_image *back = rs_image_read(exr, &err);
    if (!back) fail_msg("%s", err.msg);
    assert_int_equal(back->channels, 3); /* R, G, B by default */
    assert_memory_equal(back->data, img->data, sizeof(float) * 4 * 3 * 3);
    rs_image_free(back);

    const char *png = rs_test_path(tmp, "by_ext.PNG");
    rs_image_write_opts half_scale = {.scale = 0.5f};
    assert_int_equal(rs_image_write(img, png, &half_scale, &err), 0);
    back = rs_image_read(png, &err);
    if (!back) fail_msg("%s", err.msg);
    assert_float_equal(back->data[6], 0.5f * img->data[6], 2e-3);
    rs_image_free(back);

    const char *hdr = rs_test_path(tmp, "by_ext.hdr");
    assert_int_equal(rs_image_write(img, hdr, NULL, &err), -1);
    assert_int_equal(err.kind, RS_ERR_INPUT);
    assert_err_mentions(&err, hdr, "cannot write Radiance .hdr");
    assert_int_equal(rs_image_write(img, rs_test_path(tmp, "by_ext.tif"), NULL, &err), -1);
    assert_err_mentions(&err, "by_ext.tif", "expected a name ending in .exr or .png");
    rs_image_free(img);

    const char *fake = rs_test_path(tmp, "fake.jpg");
    write_bytes(fake, "GIF89a not a JPEG", 17);
    assert_null(rs_image_read(fake, &err));
    assert_err_mentions(&err, fake, "the name says JPEG but the content does not");
    assert_no_temporaries(tmp);
}

/* The preview's 8-bit codes are exactly round(255 sRGB(v)) for every value, also those within a
 * float step of a code's boundary (the writer finds codes by a threshold search). */
static void test_png_codes_exact(void **state)
{
    (void)state;
    enum { N = 256 * 8 };
    rs_image *img = rs_image_new(N, 1, 1);
    for (int i = 0; i < N; i++) {
        int c = i / 8, k = i % 8;
        float t = rs_srgb_to_linear((c + 0.5f) / 255.0f);
        float v = k < 4 ? t : (float)(i % 5) / 4.0f * rs_srgb_to_linear((c + 1.0f) / 255.0f);
        for (int s = 0; s < k % 4; s++) v = nextafterf(v, (k % 2) ? 2.0f : 0.0f);
        img->data[i] = v;
    }
    const char *p = rs_test_path(tmp, "codes.png");
    rs_err err = {0};
    assert_int_equal(rs_image_write_png(img, p, 1.0f, &err), 0);
    int w, h, ch;
    unsigned char *px = stbi_load(p, &w, &h, &ch, 1);
    assert_non_null(px);
    assert_int_equal(w, N);
    for (int i = 0; i < N; i++) {
        float v = img->data[i] > 1 ? 1 : img->data[i];
        int want = (int)(rs_linear_to_srgb(v) * 255.0f + 0.5f);
        if (px[i] != want) fail_msg("value %.9g: code %d, expected %d", (double)v, px[i], want);
    }
    stbi_image_free(px);
    rs_image_free(img);
}

/* Every truncation and many corrupted copies of a valid file must fail cleanly or succeed;
 * never crash (run under RHOSCAN_SANITIZE to make that strict). */
static void mangle(const unsigned char *good, size_t n, const char *kind)
{
    unsigned char *bad = malloc(n);
    char name[64];
    for (size_t cut = 0; cut < n; cut++) {
        rs_err err = {0};
        snprintf(name, sizeof name, "cut-%zu.%s", cut, kind);
        rs_image *img = rs_image_read_mem(good, cut, name, &err);
        /* A cut EXR may still decode (trailing chunks are reconstructed); others must not
         * pretend to succeed with an empty input. */
        if (!img) assert_err_mentions(&err, name, NULL);
        if (cut == 0) assert_null(img);
        rs_image_free(img);
    }
    uint32_t seed = 12345;
    for (int trial = 0; trial < 3000; trial++) {
        memcpy(bad, good, n);
        for (int k = 0; k < 1 + trial % 4; k++) {
            seed = seed * 1664525u + 1013904223u;
            size_t at = (seed >> 8) % n;
            seed = seed * 1664525u + 1013904223u;
            bad[at] = (unsigned char)(trial % 3 == 0 ? bad[at] ^ (1u << (seed >> 29)) : seed >> 24);
        }
        rs_err err = {0};
        rs_image *img = rs_image_read_mem(bad, n, "bad", &err);
        if (!img) assert_err_mentions(&err, "bad", NULL);
        rs_image_free(img);
    }
    free(bad);
}

/* A panorama-sized file decodes its chunks on every thread (image_exr.c): the same pixels with
 * one thread and with two, and a damaged chunk still fails cleanly, naming the file. */
static void test_exr_many_chunks(void **state)
{
    (void)state;
    static const char *rgb[] = {"R", "G", "B"};
    enum { W = 96, H = 640 }; /* 40 chunks of 16 ZIP lines */
    rs_image *img = rs_image_new(W, H, 3);
    for (size_t i = 0; i < (size_t)W * H * 3; i++) img->data[i] = (float)((i * 7919) % 1013) * 0.01f;
    const char *p = rs_test_path(tmp, "many.exr");
    rs_err err = {0};
    assert_int_equal(rs_image_write_exr(img, p, rgb, 0, NULL, &err), 0);
    for (int threads = 1; threads <= 2; threads++) {
        omp_set_num_threads(threads);
        rs_image *back = rs_image_read(p, &err);
        assert_non_null(back);
        assert_memory_equal(back->data, img->data, (size_t)W * H * 3 * sizeof(float));
        rs_image_free(back);
    }
    size_t n;
    unsigned char *good = slurp(p, &n), *bad = malloc(n);
    int failed = 0;
    for (int trial = 0; trial < 200; trial++) { /* bytes of chunks in the file's second half */
        memcpy(bad, good, n);
        size_t at = n / 2 + (size_t)trial * (n / 2 - 1) / 200;
        bad[at] ^= 0x5a;
        err = (rs_err){0};
        rs_image *back = rs_image_read_mem(bad, n, "damaged.exr", &err);
        if (!back) assert_err_mentions(&err, "damaged.exr", "OpenEXR");
        failed += !back;
        rs_image_free(back);
    }
    assert_true(failed > 20); /* damaged deflate streams do not decode */
    free(bad);
    free(good);
    rs_image_free(img);
}

static void test_bad_inputs(void **state)
{
    static const char *rgb[] = {"R", "G", "B"};
    rs_image *img = rs_image_new(9, 40, 3);
    for (size_t i = 0; i < 9 * 40 * 3; i++) img->data[i] = (float)(i % 17) * 0.3f;
    const char *p = rs_test_path(tmp, "good.exr");
    rs_err err = {0};
    assert_int_equal(rs_image_write_exr(img, p, rgb, 1, "note", &err), 0);
    size_t n;
    unsigned char *good = slurp(p, &n);

    /* A truncated file: pixel chunks missing. */
    const char *cut = rs_test_path(tmp, "cut.exr");
    write_bytes(cut, good, n - 40);
    assert_null(rs_image_read(cut, &err));
    assert_err_mentions(&err, cut, "OpenEXR");
    write_bytes(cut, good, 30);
    assert_null(rs_image_read(cut, &err));
    assert_err_mentions(&err, cut, "OpenEXR");
    mangle(good, n, "exr");
    free(good);

    const char *garbage = rs_test_path(tmp, "garbage.exr");
    write_bytes(garbage, "GIF89a not an image at all", 26);
    assert_null(rs_image_read(garbage, &err));
    assert_err_mentions(&err, garbage, "expected an OpenEXR");
    const char *empty = rs_test_path(tmp, "empty.exr");
    write_bytes(empty, "", 0);
    assert_null(rs_image_read(empty, &err));
    assert_err_mentions(&err, empty, "empty");
    const char *none = rs_test_path(tmp, "does-not-exist.exr");
    assert_null(rs_image_read(none, &err));
    assert_err_mentions(&err, none, NULL);

    /* PNG and HDR mangled too. */
    const char *png = rs_test_path(tmp, "m.png");
    assert_int_equal(rs_image_write_png(img, png, 1.0f, &err), 0);
    good = slurp(png, &n);
    mangle(good, n, "png");
    free(good);
    size_t hn = 0;
    void *b[2] = {NULL, &hn};
    assert_true(stbi_write_hdr_to_func(collect, b, 9, 40, 3, img->data));
    mangle(b[0], hn, "hdr");
    free(b[0]);
    rs_image_free(img);
}

/* RHOSCAN_SHARED_DIR when present; otherwise skip (fail under CI=true). */
static const char *shared_or_skip(void)
{
    const char *d = getenv("RHOSCAN_SHARED_DIR");
    struct stat st;
    if (d && stat(d, &st) == 0 && S_ISDIR(st.st_mode)) return d;
    const char *ci = getenv("CI");
    if (ci && strcmp(ci, "true") == 0) fail_msg("RHOSCAN_SHARED_DIR missing under CI=true");
    return NULL;
}

static void assert_all_finite(const rs_image *img)
{
    size_t n = (size_t)img->width * img->height * img->channels;
    for (size_t i = 0; i < n; i++)
        if (!isfinite(img->data[i])) fail_msg("value %zu is %g", i, img->data[i]);
}

static void test_shared_pano_exr(void **state)
{
    const char *d = shared_or_skip();
    if (!d) skip();
    rs_err err = {0};
    rs_image *img = rs_image_read(rs_test_path(d, "reference/two_planes_sky/pano.exr"), &err);
    if (!img) fail_msg("%s", err.msg);
    assert_int_equal(img->width, 1024);
    assert_int_equal(img->height, 512);
    assert_int_equal(img->channels, 3);
    assert_all_finite(img);
    rs_image_free(img);
}

static void test_shared_sky_hdr(void **state)
{
    const char *d = shared_or_skip();
    if (!d) skip();
    rs_err err = {0};
    rs_image *img = rs_image_read(rs_test_path(d, "skies/pmndrs_park.hdr"), &err);
    if (!img) fail_msg("%s", err.msg);
    assert_int_equal(img->width, 1024);
    assert_int_equal(img->height, 512);
    assert_int_equal(img->channels, 3);
    float mx = 0;
    for (size_t i = 0; i < (size_t)1024 * 512 * 3; i++) mx = fmaxf(mx, img->data[i]);
    assert_true(mx > 5e4f);
    rs_image_free(img);
}

/* Debian's blender-data skies are DWAB-compressed, which OpenEXR 3.1's C library cannot
 * decode; the reader falls back to OpenEXR's C++ library (exr_dwa.h) and must give a finite
 * 2:1 panorama. */
static void test_blender_dwa(void **state)
{
    const char *p = "/usr/share/blender/datafiles/studiolights/world/courtyard.exr";
    if (!rs_file_exists(p)) skip();
    rs_err err = {0};
    rs_image *img = rs_image_read(p, &err);
    if (!img) fail_msg("%s: %s", err.file, err.msg);
    assert_int_equal(img->channels, 3);
    assert_int_equal(img->width, 2 * img->height);
    assert_all_finite(img);
    double sum = 0;
    for (size_t i = 0; i < (size_t)img->width * img->height * 3; i++) sum += img->data[i];
    assert_true(sum > 0);
    rs_image_free(img);
}

RS_TEST_MAIN(setup, teardown, cmocka_unit_test(test_srgb), cmocka_unit_test(test_png_codes_exact),
             cmocka_unit_test(test_new_rejects_bad_sizes), cmocka_unit_test(test_exr_round_trip),
             cmocka_unit_test(test_exr_many_chunks), cmocka_unit_test(test_exr_note_and_determinism),
             cmocka_unit_test(test_exr_windows_tiles_types), cmocka_unit_test(test_exr_channel_errors),
             cmocka_unit_test(test_exr_write_failure), cmocka_unit_test(test_hdr_from_memory),
             cmocka_unit_test(test_hdr_nul_header_zero_run), cmocka_unit_test(test_png_chunk_past_end),
             cmocka_unit_test(test_exr_subsampled_channel), cmocka_unit_test(test_png_linearised),
             cmocka_unit_test(test_jpeg_and_stb_guards), cmocka_unit_test(test_png_preview_round_trip), cmocka_unit_test(test_write_by_extension),
             cmocka_unit_test(test_bad_inputs), cmocka_unit_test(test_shared_pano_exr),
             cmocka_unit_test(test_shared_sky_hdr), cmocka_unit_test(test_blender_dwa))

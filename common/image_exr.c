/* image_exr: OpenEXR files through the OpenEXR core C API (see image_exr.h): reading
 * (scanline or tiled, any compression the library decodes) and writing (ZIP, float or half). */
#include "common/image_exr.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <openexr.h>

#include "common/exr_dwa.h"
#include "common/fileio.h"

/* What the OpenEXR callbacks share: the input bytes when reading, a growing buffer when
 * writing (written to disk atomically at the end), and the library's first error message,
 * which its default handler would have printed to stderr. */
typedef struct exr_io {
    const unsigned char *in;
    size_t in_size;
    unsigned char *out;
    size_t out_size, out_cap;
    char msg[512];
} exr_io;

static void exr_on_error(exr_const_context_t ctxt, exr_result_t code, const char *msg)
{
    void *ud = NULL;
    if (exr_get_user_data(ctxt, &ud) != EXR_ERR_SUCCESS || !ud) return;
    exr_io *io = ud;
    if (!io->msg[0]) snprintf(io->msg, sizeof io->msg, "%s", msg ? msg : exr_get_default_error_message(code));
}

static int64_t exr_mem_read(exr_const_context_t ctxt, void *ud, void *buf, uint64_t sz, uint64_t offset,
                            exr_stream_error_func_ptr_t error_cb)
{
    const exr_io *io = ud;
    if (offset >= io->in_size) return 0;
    uint64_t n = io->in_size - offset;
    if (n > sz) n = sz;
    memcpy(buf, io->in + offset, (size_t)n);
    return (int64_t)n;
}

static int64_t exr_mem_size(exr_const_context_t ctxt, void *ud)
{
    return (int64_t)((const exr_io *)ud)->in_size;
}

/* pwrite semantics: the library seeks back to fill in the chunk offset table. */
static int64_t exr_mem_write(exr_const_context_t ctxt, void *ud, const void *buf, uint64_t sz, uint64_t offset,
                             exr_stream_error_func_ptr_t error_cb)
{
    exr_io *io = ud;
    if (offset > (uint64_t)(SIZE_MAX / 2) || sz > (uint64_t)(SIZE_MAX / 2) - offset) return -1;
    size_t end = (size_t)(offset + sz);
    if (end > io->out_cap) {
        size_t cap = io->out_cap ? io->out_cap : 65536;
        while (cap < end) cap *= 2;
        unsigned char *p = realloc(io->out, cap);
        if (!p) return -1;
        io->out = p;
        io->out_cap = cap;
    }
    if (offset > io->out_size) memset(io->out + io->out_size, 0, (size_t)offset - io->out_size);
    memcpy(io->out + offset, buf, (size_t)sz);
    if (end > io->out_size) io->out_size = end;
    return (int64_t)sz;
}

static int exr_fail(const exr_io *io, exr_result_t rv, const char *name, const char *what, rs_err *err)
{
    const char *why = io->msg[0] ? io->msg : exr_get_default_error_message(rv);
    return rs_err_set(err, RS_ERR_INPUT, name, 0, "OpenEXR: %s: %s", what, why);
}

/* Chooses the channels to read, by name: R,G,B (others such as A ignored), else the only
 * channel, else Y (with at most an A beside it). */
static int exr_pick_channels(const exr_attr_chlist_t *chl, const char *sel[3], int *nsel, const char *name, rs_err *err)
{
    int r = -1, g = -1, b = -1, y = -1, a = -1;
    for (int i = 0; i < chl->num_channels; i++) {
        const exr_attr_chlist_entry_t *e = &chl->entries[i];
        /* Any subsampled channel, even one not read: OpenEXR 3.1's decoder writes through a null
         * pointer on such a file (fuzzing found it: corpus/image/segv-exr-subsampled-alpha.exr). */
        if (e->x_sampling != 1 || e->y_sampling != 1)
            return rs_err_set(err, RS_ERR_INPUT, name, 0,
                              "EXR channel %s is subsampled (%d x %d): expected full resolution",
                              e->name.str ? e->name.str : "?", e->x_sampling, e->y_sampling);
        const char *s = e->name.str;
        if (!s) continue;
        if (strcmp(s, "R") == 0)
            r = i;
        else if (strcmp(s, "G") == 0)
            g = i;
        else if (strcmp(s, "B") == 0)
            b = i;
        else if (strcmp(s, "Y") == 0)
            y = i;
        else if (strcmp(s, "A") == 0)
            a = i;
    }
    int idx[3], n = 0;
    if (r >= 0 && g >= 0 && b >= 0) {
        idx[0] = r, idx[1] = g, idx[2] = b, n = 3;
    } else if (chl->num_channels == 1) {
        idx[0] = 0, n = 1;
    } else if (y >= 0 && chl->num_channels == 2 && a >= 0) {
        idx[0] = y, n = 1;
    } else {
        char list[512] = "";
        size_t len = 0;
        for (int i = 0; i < chl->num_channels && len < sizeof list - 1; i++)
            len += (size_t)snprintf(list + len, sizeof list - len, "%s%s", i ? "," : "",
                                    chl->entries[i].name.str ? chl->entries[i].name.str : "?");
        return rs_err_set(err, RS_ERR_INPUT, name, 0,
                          "EXR channels {%s}: expected R,G,B (A ignored), Y, or a single channel", list);
    }
    for (int k = 0; k < n; k++) sel[k] = chl->entries[idx[k]].name.str;
    *nsel = n;
    return 0;
}

/* The part of the file being read and where its pixels go. */
typedef struct exr_reader {
    exr_context_t ctx;
    exr_io io;
    const char *name;
    const char *sel[3];
    int nsel;
    exr_attr_box2i_t dw, disp; /* data and display windows (inclusive) */
    rs_image *img;             /* covers the display window */
    float *tmp;                /* one decoded chunk, planar per selected channel */
    size_t tmp_cap;
} exr_reader;

/* Decodes one chunk whose top-left pixel is at (x0, y0) in file coordinates, and copies the
 * part of it inside the display window into the image. */
static int exr_decode_chunk(exr_reader *rd, const exr_chunk_info_t *ci, int64_t x0, int64_t y0, rs_err *err)
{
    int64_t w = ci->width, h = ci->height;
    if (w <= 0 || h <= 0 || x0 < rd->dw.min.x || y0 < rd->dw.min.y || x0 + w - 1 > rd->dw.max.x ||
        y0 + h - 1 > rd->dw.max.y)
        return rs_err_set(err, RS_ERR_INPUT, rd->name, 0,
                          "EXR chunk at (%lld, %lld) of %lld x %lld pixels lies outside the "
                          "data window",
                          (long long)x0, (long long)y0, (long long)w, (long long)h);
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    exr_result_t rv = exr_decoding_initialize(rd->ctx, 0, ci, &dec);
    if (rv != EXR_ERR_SUCCESS) {
        exr_decoding_destroy(rd->ctx, &dec);
        return exr_fail(&rd->io, rv, rd->name, "cannot start decoding", err);
    }
    /* Every channel gets a plane, the unwanted ones (alpha, extra passes) too: OpenEXR 3.1's
     * generic unpacker reads out of bounds when some decode_to_ptr are NULL (it crashed on
     * Blender's half RGBA files). Selected channels take planes 0..nsel-1. */
    if (dec.channel_count > 64) { /* every channel gets a plane: bound what a header can ask */
        exr_decoding_destroy(rd->ctx, &dec);
        return rs_err_set(err, RS_ERR_INPUT, rd->name, 0, "EXR with %d channels: expected at most 64",
                          (int)dec.channel_count);
    }
    int nplanes = dec.channel_count > rd->nsel ? dec.channel_count : rd->nsel;
    size_t plane = (size_t)w * (size_t)h, need = plane * (size_t)nplanes;
    if (need > rd->tmp_cap) {
        float *p = realloc(rd->tmp, need * sizeof(float));
        if (!p) {
            exr_decoding_destroy(rd->ctx, &dec);
            return rs_err_set(err, RS_ERR_SYSTEM, rd->name, 0, "out of memory");
        }
        rd->tmp = p;
        rd->tmp_cap = need;
    }
    memset(rd->tmp, 0, need * sizeof(float));
    int found = 0, spare = rd->nsel;
    for (int c = 0; c < dec.channel_count; c++) {
        exr_coding_channel_info_t *ch = &dec.channels[c];
        int slot = -1;
        for (int k = 0; k < rd->nsel; k++)
            if (strcmp(ch->channel_name, rd->sel[k]) == 0 && ch->width == w && ch->height == h) slot = k;
        if (slot >= 0)
            found++;
        else if (ch->width != w || ch->height != h) { /* subsampled, unwanted: skip safely */
            ch->decode_to_ptr = NULL;
            continue;
        } else
            slot = spare++;
        ch->decode_to_ptr = (uint8_t *)(rd->tmp + (size_t)slot * plane);
        ch->user_pixel_stride = (int32_t)sizeof(float);
        ch->user_line_stride = (int32_t)(sizeof(float) * (size_t)w);
        ch->user_bytes_per_element = (int16_t)sizeof(float);
        ch->user_data_type = EXR_PIXEL_FLOAT;
    }
    if (found != rd->nsel) {
        exr_decoding_destroy(rd->ctx, &dec);
        return rs_err_set(err, RS_ERR_INPUT, rd->name, 0, "EXR chunk at y = %lld holds %d of the %d channels expected",
                          (long long)y0, found, rd->nsel);
    }
    rv = exr_decoding_choose_default_routines(rd->ctx, 0, &dec);
    if (rv == EXR_ERR_SUCCESS) rv = exr_decoding_run(rd->ctx, 0, &dec);
    exr_decoding_destroy(rd->ctx, &dec);
    if (rv == EXR_ERR_FEATURE_NOT_IMPLEMENTED) {
        /* OpenEXR 3.1's C library has no DWAA/DWAB decoder (Blender's bundled skies use it). */
        static const char *const names[] = {"NONE",  "RLE", "ZIPS", "ZIP",  "PIZ",
                                            "PXR24", "B44", "B44A", "DWAA", "DWAB"};
        exr_compression_t comp = EXR_COMPRESSION_LAST_TYPE;
        exr_get_compression(rd->ctx, 0, &comp);
        int known = comp >= 0 && comp < EXR_COMPRESSION_LAST_TYPE;
        return rs_err_set(err, RS_ERR_INPUT, rd->name, 0,
                          "EXR compression %s cannot be decoded by this OpenEXR C library (%s): "
                          "expected NONE, RLE, ZIPS, ZIP, PIZ, PXR24, B44 or B44A; re-save the "
                          "image with ZIP compression",
                          known ? names[comp] : "?", rd->io.msg[0] ? rd->io.msg : "the library has no decoder for it");
    }
    if (rv != EXR_ERR_SUCCESS) return exr_fail(&rd->io, rv, rd->name, "cannot decode pixels", err);

    /* Copy the rows and columns that fall inside the display window. */
    for (int64_t r = 0; r < h; r++) {
        int64_t y = y0 + r;
        if (y < rd->disp.min.y || y > rd->disp.max.y) continue;
        for (int64_t c = 0; c < w; c++) {
            int64_t x = x0 + c;
            if (x < rd->disp.min.x || x > rd->disp.max.x) continue;
            float *px = rs_image_px(rd->img, (int)(x - rd->disp.min.x), (int)(y - rd->disp.min.y));
            for (int k = 0; k < rd->nsel; k++) px[k] = rd->tmp[(size_t)k * plane + (size_t)(r * w + c)];
        }
    }
    return 0;
}

/* Chunks decoded on every thread, each with its own pipeline and buffer (the core library's
 * context may be shared for reading: openexr_decode.h). Returns 0 when every chunk decoded, -1
 * otherwise; the caller then decodes serially, which names the first bad chunk the same way
 * whatever the thread count. Reading a 2048 x 1024 panorama was a tenth of some stages. */
static int exr_read_scanlines_parallel(exr_reader *rd, int32_t lines)
{
    int64_t nchunks = ((int64_t)rd->dw.max.y - rd->dw.min.y) / lines + 1;
    int failed = 0;
#pragma omp parallel reduction(| : failed)
    {
        exr_reader mine = *rd; /* the shared context and image; a buffer of its own */
        mine.tmp = NULL;
        mine.tmp_cap = 0;
#pragma omp for schedule(dynamic, 8)
        for (int64_t i = 0; i < nchunks; i++) {
            exr_chunk_info_t ci;
            if (failed) continue;
            if (exr_read_scanline_chunk_info(mine.ctx, 0, (int)(rd->dw.min.y + i * lines), &ci) != EXR_ERR_SUCCESS ||
                exr_decode_chunk(&mine, &ci, rd->dw.min.x, ci.start_y, NULL) != 0)
                failed = 1;
        }
        free(mine.tmp);
    }
    return failed ? -1 : 0;
}

static int exr_read_scanlines(exr_reader *rd, rs_err *err)
{
    int32_t lines = 0;
    exr_result_t rv = exr_get_scanlines_per_chunk(rd->ctx, 0, &lines);
    if (rv != EXR_ERR_SUCCESS || lines <= 0) return exr_fail(&rd->io, rv, rd->name, "no scanlines per chunk", err);
    int64_t rows = (int64_t)rd->dw.max.y - rd->dw.min.y + 1;
    if (rows / lines >= 16) {
        if (exr_read_scanlines_parallel(rd, lines) == 0) return 0;
        rd->io.msg[0] = 0; /* the serial pass below says what went wrong */
    }
    for (int64_t y = rd->dw.min.y; y <= rd->dw.max.y; y += lines) {
        exr_chunk_info_t ci;
        rv = exr_read_scanline_chunk_info(rd->ctx, 0, (int)y, &ci);
        if (rv != EXR_ERR_SUCCESS) return exr_fail(&rd->io, rv, rd->name, "cannot locate a block of scanlines", err);
        if (exr_decode_chunk(rd, &ci, rd->dw.min.x, ci.start_y, err) != 0) return -1;
    }
    return 0;
}

/* Tiled parts: only the full-resolution level (0, 0) of mipmapped or ripmapped files. */
static int exr_read_tiles(exr_reader *rd, rs_err *err)
{
    int32_t tw = 0, th = 0, lw = 0, lh = 0;
    exr_result_t rv = exr_get_tile_sizes(rd->ctx, 0, 0, 0, &tw, &th);
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_level_sizes(rd->ctx, 0, 0, 0, &lw, &lh);
    if (rv != EXR_ERR_SUCCESS) return exr_fail(&rd->io, rv, rd->name, "bad tile description", err);
    if (tw <= 0 || th <= 0 || lw <= 0 || lh <= 0)
        return rs_err_set(err, RS_ERR_INPUT, rd->name, 0,
                          "EXR tiles of %d x %d on a level of %d x %d: expected positive sizes", tw, th, lw, lh);
    int64_t ntx = ((int64_t)lw + tw - 1) / tw, nty = ((int64_t)lh + th - 1) / th;
    for (int64_t ty = 0; ty < nty; ty++) {
        for (int64_t tx = 0; tx < ntx; tx++) {
            exr_chunk_info_t ci;
            rv = exr_read_tile_chunk_info(rd->ctx, 0, (int)tx, (int)ty, 0, 0, &ci);
            if (rv != EXR_ERR_SUCCESS) return exr_fail(&rd->io, rv, rd->name, "cannot locate a tile", err);
            if (exr_decode_chunk(rd, &ci, rd->dw.min.x + tx * tw, rd->dw.min.y + ty * th, err)) return -1;
        }
    }
    return 0;
}

/* The result covers the display window (which is what maps onto the sphere for a
 * panorama); pixels outside the data window stay 0, data outside the display is dropped. */
rs_image *rs_image_exr_read_mem(const void *data, size_t size, const char *name, rs_err *err)
{
    exr_reader rd;
    memset(&rd, 0, sizeof rd);
    rd.name = name;
    rd.io.in = data;
    rd.io.in_size = size;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = exr_on_error;
    init.user_data = &rd.io;
    init.read_fn = exr_mem_read;
    init.size_fn = exr_mem_size;
    init.max_image_width = RS_IMAGE_MAX_SIDE;
    init.max_image_height = RS_IMAGE_MAX_SIDE;

    rs_image *result = NULL;
    exr_result_t rv = exr_start_read(&rd.ctx, name, &init);
    if (rv != EXR_ERR_SUCCESS) {
        exr_fail(&rd.io, rv, name, "cannot read the header", err);
        goto out;
    }
    exr_storage_t storage;
    const exr_attr_chlist_t *chl = NULL;
    rv = exr_get_storage(rd.ctx, 0, &storage);
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_channels(rd.ctx, 0, &chl);
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_data_window(rd.ctx, 0, &rd.dw);
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_display_window(rd.ctx, 0, &rd.disp);
    if (rv != EXR_ERR_SUCCESS || !chl) {
        exr_fail(&rd.io, rv, name, "incomplete header", err);
        goto out;
    }
    if (storage != EXR_STORAGE_SCANLINE && storage != EXR_STORAGE_TILED) {
        rs_err_set(err, RS_ERR_INPUT, name, 0,
                   "deep EXR data: expected a flat scanline or "
                   "tiled image");
        goto out;
    }
    if (exr_pick_channels(chl, rd.sel, &rd.nsel, name, err) != 0) goto out;
    long long dw_w = (long long)rd.dw.max.x - rd.dw.min.x + 1;
    long long dw_h = (long long)rd.dw.max.y - rd.dw.min.y + 1;
    long long w = (long long)rd.disp.max.x - rd.disp.min.x + 1;
    long long h = (long long)rd.disp.max.y - rd.disp.min.y + 1;
    if (rs_image_check_size(dw_w, dw_h, name, err) != 0 || rs_image_check_size(w, h, name, err) != 0) goto out;
    if (rd.dw.max.x < rd.disp.min.x || rd.dw.min.x > rd.disp.max.x || rd.dw.max.y < rd.disp.min.y ||
        rd.dw.min.y > rd.disp.max.y) {
        rs_err_set(err, RS_ERR_INPUT, name, 0,
                   "EXR data window (%d,%d)-(%d,%d) lies outside the display window "
                   "(%d,%d)-(%d,%d): expected them to overlap",
                   rd.dw.min.x, rd.dw.min.y, rd.dw.max.x, rd.dw.max.y, rd.disp.min.x, rd.disp.min.y, rd.disp.max.x,
                   rd.disp.max.y);
        goto out;
    }
    rd.img = rs_image_new_or_fail((int)w, (int)h, rd.nsel, name, err);
    if (!rd.img) goto out;
    exr_compression_t comp = EXR_COMPRESSION_NONE;
    if (exr_get_compression(rd.ctx, 0, &comp) == EXR_ERR_SUCCESS &&
        (comp == EXR_COMPRESSION_DWAA || comp == EXR_COMPRESSION_DWAB)) {
        /* OpenEXR 3.1's C library cannot decode DWA; its C++ library can (exr_dwa.h). */
        char msg[256];
        if (rs_exr_cxx_read(data, size, rd.sel, rd.nsel, rd.disp.min.x, rd.disp.min.y, (int)w, (int)h, rd.img->data,
                            msg, sizeof msg) != 0) {
            rs_err_set(err, RS_ERR_INPUT, name, 0, "DWA-compressed EXR could not be decoded: %s", msg);
            goto out;
        }
        result = rd.img;
        rd.img = NULL;
        goto out;
    }
    int bad = storage == EXR_STORAGE_TILED ? exr_read_tiles(&rd, err) : exr_read_scanlines(&rd, err);
    if (bad) goto out;
    result = rd.img;
    rd.img = NULL;
out:
    if (rd.ctx) exr_finish(&rd.ctx);
    rs_image_free(rd.img);
    free(rd.tmp);
    return result;
}

int rs_image_write_exr(const rs_image *img, const char *path, const char *const *names, int half, const char *note,
                       rs_err *err)
{
    if (!img || !img->data || img->channels <= 0 || !names)
        return rs_err_set(err, RS_ERR_INTERNAL, path, 0, "rs_image_write_exr: no image or names");
    if (rs_image_check_size(img->width, img->height, path, err) != 0) return -1;
    for (int c = 0; c < img->channels; c++)
        if (!names[c] || !names[c][0])
            return rs_err_set(err, RS_ERR_INTERNAL, path, 0, "rs_image_write_exr: channel %d has no name", c);

    exr_io io;
    memset(&io, 0, sizeof io);
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = exr_on_error;
    init.user_data = &io;
    init.write_fn = exr_mem_write;

    exr_context_t ctx = NULL;
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    int enc_started = 0, status = -1, part = 0;
    const char *step = "cannot start writing";
    exr_result_t rv = exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv == EXR_ERR_SUCCESS) rv = exr_add_part(ctx, "rhoscan", EXR_STORAGE_SCANLINE, &part);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_initialize_required_attr_simple(ctx, part, img->width, img->height, EXR_COMPRESSION_ZIP);
    /* zlib's fastest level: the default (6) spent half the render stage in deflate at 2048 x 1024
     * (perf) for files about a tenth smaller. */
    if (rv == EXR_ERR_SUCCESS) rv = exr_set_zip_compression_level(ctx, part, 1);
    for (int c = 0; c < img->channels && rv == EXR_ERR_SUCCESS; c++)
        rv = exr_add_channel(ctx, part, names[c], half ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT, EXR_PERCEPTUALLY_LOGARITHMIC,
                             1, 1);
    if (rv == EXR_ERR_SUCCESS && note) rv = exr_attr_set_string(ctx, part, "rhoscan", note);
    if (rv == EXR_ERR_SUCCESS) rv = exr_write_header(ctx);
    int32_t lines = 0;
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_scanlines_per_chunk(ctx, part, &lines);
    if (rv != EXR_ERR_SUCCESS) goto fail;
    step = "cannot encode pixels";
    size_t row_bytes = sizeof(float) * (size_t)img->width * (size_t)img->channels;
    for (int y = 0; y < img->height; y += lines) {
        exr_chunk_info_t ci;
        rv = exr_write_scanline_chunk_info(ctx, part, y, &ci);
        if (rv != EXR_ERR_SUCCESS) goto fail;
        rv = enc_started ? exr_encoding_update(ctx, part, &ci, &enc) : exr_encoding_initialize(ctx, part, &ci, &enc);
        if (rv != EXR_ERR_SUCCESS) goto fail;
        /* The file orders channels alphabetically: match them to ours by name. */
        for (int e = 0; e < enc.channel_count; e++) {
            exr_coding_channel_info_t *ch = &enc.channels[e];
            int src = 0;
            while (src < img->channels && strcmp(names[src], ch->channel_name) != 0) src++;
            if (src == img->channels) {
                rv = EXR_ERR_INVALID_ARGUMENT;
                goto fail;
            }
            ch->encode_from_ptr =
                (const uint8_t *)(img->data + (size_t)y * (size_t)img->width * (size_t)img->channels + (size_t)src);
            ch->user_pixel_stride = (int32_t)(sizeof(float) * (size_t)img->channels);
            ch->user_line_stride = (int32_t)row_bytes;
            ch->user_bytes_per_element = (int16_t)sizeof(float);
            ch->user_data_type = EXR_PIXEL_FLOAT;
        }
        if (!enc_started) {
            enc_started = 1;
            rv = exr_encoding_choose_default_routines(ctx, part, &enc);
            if (rv != EXR_ERR_SUCCESS) goto fail;
        }
        rv = exr_encoding_run(ctx, part, &enc);
        if (rv != EXR_ERR_SUCCESS) goto fail;
    }
    step = "cannot finish the file";
    if (enc_started) exr_encoding_destroy(ctx, &enc);
    enc_started = 0;
    rv = exr_finish(&ctx);
    ctx = NULL;
    if (rv != EXR_ERR_SUCCESS) goto fail;
    status = rs_write_file_atomic(path, io.out, io.out_size, err);
    goto out;
fail:
    rs_err_set(err, RS_ERR_INTERNAL, path, 0, "OpenEXR: %s: %s", step,
               io.msg[0] ? io.msg : exr_get_default_error_message(rv));
out:
    if (enc_started) exr_encoding_destroy(ctx, &enc);
    if (ctx) exr_finish(&ctx);
    free(io.out);
    return status;
}

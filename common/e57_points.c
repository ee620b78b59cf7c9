/* e57_points: compressed vectors (ASTM E2807, section 9): a binary section of data packets
 * (index and empty packets skipped), each carrying a piece of every prototype field's
 * bytestream; the bytestreams hold the records' values bit-packed, least significant bit first
 * (bitPackCodec): Integer and ScaledInteger in ceil(log2(max - min + 1)) bits from the minimum,
 * Float in 32 or 64 bits. A value may cross byte, word and packet boundaries. */
#include "common/e57_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "the E57 bit unpacking assumes a little-endian machine"
#endif

#define SLACK 16 /* bytes past a buffer's end that may be loaded (zeros) */

static uint64_t physical_of(uint64_t logical)
{
    return logical / E57_PAGE_DATA * E57_PAGE + logical % E57_PAGE_DATA;
}

static uint64_t le64(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--) v = v << 8 | p[i];
    return v;
}

/* bits needed for the values 0 .. range */
static int bits_for(uint64_t range)
{
    int b = 0;
    while (range) {
        b++;
        range >>= 1;
    }
    return b;
}

static int add_field(e57_cv *cv, const e57_node *n, int role, const char *file, rs_err *err)
{
    e57_field *fl = realloc(cv->fields, (size_t)(cv->nfields + 1) * sizeof *fl);
    if (!fl) return rs_err_set(err, RS_ERR_SYSTEM, file, 0, "out of memory");
    cv->fields = fl;
    e57_field *d = &fl[cv->nfields];
    memset(d, 0, sizeof *d);
    e57_path(n, d->path, sizeof d->path);
    d->role = role;
    d->type = n->type;
    d->scale = 1;
    if (n->type == E57_T_FLOAT) {
        const char *p = e57_attr(n, "precision");
        d->bits = p && strcmp(p, "single") == 0 ? 32 : 64;
    } else if (n->type == E57_T_INTEGER || n->type == E57_T_SCALED) {
        if (e57_attr_int(n, "minimum", INT64_MIN, file, &d->min, err) != 0 ||
            e57_attr_int(n, "maximum", INT64_MAX, file, &d->max, err) != 0)
            return -1;
        if (n->type == E57_T_SCALED &&
            (e57_attr_real(n, "scale", 1, file, &d->scale, err) != 0 ||
             e57_attr_real(n, "offset", 0, file, &d->offset, err) != 0))
            return -1;
        if (d->max < d->min)
            return rs_err_set(err, RS_ERR_INPUT, file, n->line, "XML %s: maximum %lld is below minimum %lld", d->path,
                              (long long)d->max, (long long)d->min);
        d->bits = bits_for((uint64_t)d->max - (uint64_t)d->min);
    } else {
        return rs_err_set(
            err, RS_ERR_INPUT, file, n->line,
            "XML %s: a %s field in a compressed vector; expected Integer, ScaledInteger or Float (rhoscan "
            "does not read String fields in points)",
            d->path, n->type == E57_T_STRING ? "String" : "non-numeric");
    }
    d->cap = 4096;
    d->buf = calloc(1, d->cap + SLACK);
    if (!d->buf) return rs_err_set(err, RS_ERR_SYSTEM, file, 0, "out of memory");
    cv->nfields++;
    return 0;
}

/* The prototype's leaves in document order (nested structures flattened). */
static int add_leaves(e57_cv *cv, const e57_node *n, int (*role_of)(const char *), const char *file, rs_err *err)
{
    for (const e57_node *c = n->child; c; c = c->next) {
        if (c->type == E57_T_STRUCT || c->type == E57_T_VECTOR) {
            if (add_leaves(cv, c, role_of, file, err) != 0) return -1;
            continue;
        }
        int role = role_of && n->parent && strcmp(n->name, "prototype") == 0 ? role_of(c->name) : E57_R_NONE;
        for (int k = 0; k < cv->nfields && role != E57_R_NONE; k++)
            if (cv->fields[k].role == role) role = E57_R_NONE; /* a repeated name: the first one counts */
        if (add_field(cv, c, role, file, err) != 0) return -1;
    }
    return 0;
}

/* codecs: only the default bitPackCodec (an empty vector, or entries naming it). */
static int check_codecs(const e57_node *codecs, const char *file, rs_err *err)
{
    for (const e57_node *c = codecs ? codecs->child : NULL; c; c = c->next)
        for (const e57_node *k = c->child; k; k = k->next)
            if (strcmp(k->name, "inputs") != 0 && strcmp(k->name, "bitPackCodec") != 0) {
                char path[256];
                e57_path(k, path, sizeof path);
                return rs_err_set(err, RS_ERR_INPUT, file, k->line,
                                  "XML %s: codec <%s>; expected bitPackCodec (the only codec E57 defines)", path,
                                  k->name);
            }
    return 0;
}

/* The binary section's 32-byte header: id 1, its logical length, the first data packet. */
static int section_header(e57_cv *cv, e57_file *f, const e57_node *node, rs_err *err)
{
    int64_t off;
    if (e57_attr_int(node, "fileOffset", -1, f->name, &off, err) != 0) return -1;
    uint64_t start, data;
    if (off < 0)
        return rs_err_set(err, RS_ERR_INPUT, f->name, node->line,
                          "XML %s: no fileOffset; expected the binary section's offset", cv->path);
    if (e57_logical_of(f, (uint64_t)off, cv->path, &start, err) != 0) return -1;
    uint8_t h[32];
    if (e57_read_logical(f, start, h, sizeof h, err) != 0) return -1;
    uint64_t length = le64(h + 8), data_phys = le64(h + 16);
    if (h[0] != 1)
        return rs_err_set(err, RS_ERR_INPUT, f->name, 0,
                          "offset %lld (%s's section): section id %d; expected 1 (a compressed vector)", (long long)off,
                          cv->path, h[0]);
    if (length < 32 || length > e57_logical_size(f) - start)
        return rs_err_set(err, RS_ERR_INPUT, f->name, 0,
                          "offset %lld (%s's section): section length %llu; expected 32 to %llu (the bytes left)",
                          (long long)off + 8, cv->path, (unsigned long long)length,
                          (unsigned long long)(e57_logical_size(f) - start));
    if (e57_logical_of(f, data_phys, "the section's dataPhysicalOffset", &data, err) != 0) return -1;
    if (data < start + 32 || data >= start + length)
        return rs_err_set(err, RS_ERR_INPUT, f->name, 0,
                          "offset %lld (%s's section): dataPhysicalOffset %llu lies outside the section; expected a "
                          "packet after its header",
                          (long long)off + 16, cv->path, (unsigned long long)data_phys);
    cv->next_packet = data;
    cv->section_end = start + length;
    return 0;
}

int e57_cv_open(e57_cv *cv, e57_file *f, const e57_node *node, int (*role_of)(const char *name), rs_err *err)
{
    memset(cv, 0, sizeof *cv);
    e57_path(node, cv->path, sizeof cv->path);
    int64_t records;
    if (node->type != E57_T_CVECTOR)
        return rs_err_set(err, RS_ERR_INPUT, f->name, node->line, "XML %s: expected a CompressedVector", cv->path);
    if (e57_attr_int(node, "recordCount", -1, f->name, &records, err) != 0) return -1;
    if (records < 0)
        return rs_err_set(err, RS_ERR_INPUT, f->name, node->line,
                          "XML %s: recordCount %lld; expected a count of 0 or more", cv->path, (long long)records);
    cv->records = (uint64_t)records;
    const e57_node *proto = e57_child(node, "prototype");
    if (!proto || proto->type != E57_T_STRUCT)
        return rs_err_set(err, RS_ERR_INPUT, f->name, node->line, "XML %s: no prototype Structure", cv->path);
    if (add_leaves(cv, proto, role_of, f->name, err) != 0 || check_codecs(e57_child(node, "codecs"), f->name, err) != 0)
        return -1;
    if (cv->records == 0) return 0;
    if (cv->nfields == 0)
        return rs_err_set(err, RS_ERR_INPUT, f->name, proto->line, "XML %s: an empty prototype for %llu records",
                          cv->path, (unsigned long long)cv->records);
    /* Every field takes at least one bit a record, except constants: the section must hold them. */
    uint64_t bits = 0;
    for (int k = 0; k < cv->nfields; k++) bits += (uint64_t)cv->fields[k].bits;
    /* Constant fields take no bits: such a vector still cannot claim more records than bits in the file. */
    if (cv->records > e57_logical_size(f) * 8 / (bits ? bits : 1))
        return rs_err_set(err, RS_ERR_INPUT, f->name, node->line,
                          "XML %s: recordCount %llu of %llu bits each exceeds the file's %llu data bytes", cv->path,
                          (unsigned long long)cv->records, (unsigned long long)bits,
                          (unsigned long long)e57_logical_size(f));
    cv->packet = malloc(65536 + SLACK);
    if (!cv->packet) return rs_err_set(err, RS_ERR_SYSTEM, f->name, 0, "out of memory");
    return section_header(cv, f, node, err);
}

void e57_cv_free(e57_cv *cv)
{
    for (int k = 0; k < cv->nfields; k++) free(cv->fields[k].buf);
    free(cv->fields);
    free(cv->packet);
    memset(cv, 0, sizeof *cv);
}

/* Appends n bytes to a field's bytestream, dropping the bytes already decoded. */
static int append(e57_field *d, const uint8_t *p, size_t n, const char *file, rs_err *err)
{
    size_t used = (size_t)(d->bit / 8);
    if (used) {
        memmove(d->buf, d->buf + used, d->len - used);
        d->len -= used;
        d->bit -= (uint64_t)used * 8;
    }
    if (d->len + n > d->cap) {
        size_t cap = d->cap;
        while (cap < d->len + n) cap *= 2;
        uint8_t *b = realloc(d->buf, cap + SLACK);
        if (!b) return rs_err_set(err, RS_ERR_SYSTEM, file, 0, "out of memory for a bytestream of %zu bytes", cap);
        d->buf = b;
        d->cap = cap;
    }
    memcpy(d->buf + d->len, p, n);
    d->len += n;
    memset(d->buf + d->len, 0, SLACK);
    return 0;
}

static int bad_packet(const e57_cv *cv, e57_file *f, uint64_t at, const char *what, rs_err *err)
{
    return rs_err_set(err, RS_ERR_INPUT, f->name, 0, "offset %llu (%s, data packet %llu): %s",
                      (unsigned long long)physical_of(at), cv->path, (unsigned long long)cv->packets + 1, what);
}

/* Reads packets up to the next data packet and appends its bytestreams; 0 when the section
 * has no more. */
static int next_packet(e57_cv *cv, e57_file *f, rs_err *err)
{
    while (cv->next_packet + 4 <= cv->section_end) {
        uint64_t at = cv->next_packet;
        uint8_t *p = cv->packet;
        if (e57_read_logical(f, at, p, 4, err) != 0) return -1;
        size_t len = (size_t)(p[2] | p[3] << 8) + 1;
        if (len < 4 || at + len > cv->section_end)
            return bad_packet(cv, f, at, "the packet's length runs past the end of its section", err);
        cv->next_packet += len;
        if (p[0] == 0 || p[0] == 2) continue; /* index and empty packets */
        if (p[0] != 1)
            return bad_packet(cv, f, at, "unknown packet type; expected 0 (index), 1 (data) or 2 (empty)", err);
        if (len < 6 || e57_read_logical(f, at, p, len, err) != 0)
            return len < 6 ? bad_packet(cv, f, at, "a data packet shorter than its 6-byte header", err) : -1;
        size_t count = (size_t)(p[4] | p[5] << 8), sum = 0;
        if (count != (size_t)cv->nfields) {
            char msg[160];
            snprintf(msg, sizeof msg, "%zu bytestreams; expected %d, one per prototype field", count, cv->nfields);
            return bad_packet(cv, f, at, msg, err);
        }
        if (6 + 2 * count > len) return bad_packet(cv, f, at, "the bytestream lengths run past the packet", err);
        for (size_t k = 0; k < count; k++) sum += (size_t)(p[6 + 2 * k] | p[7 + 2 * k] << 8);
        if (6 + 2 * count + sum > len) return bad_packet(cv, f, at, "its bytestreams run past the packet's end", err);
        const uint8_t *q = p + 6 + 2 * count;
        for (size_t k = 0; k < count; k++) {
            size_t n = (size_t)(p[6 + 2 * k] | p[7 + 2 * k] << 8);
            if (append(&cv->fields[k], q, n, f->name, err) != 0) return -1;
            q += n;
        }
        cv->packets++;
        return 1;
    }
    return 0;
}

/* bits (1..64) at bit offset b of p (least significant first; p has SLACK bytes past it). */
static inline uint64_t get_bits(const uint8_t *p, uint64_t b, int bits)
{
    const uint8_t *q = p + (b >> 3);
    unsigned sh = (unsigned)(b & 7);
    uint64_t v;
    memcpy(&v, q, 8);
    v >>= sh;
    if (sh + (unsigned)bits > 64) v |= (uint64_t)q[8] << (64 - sh);
    return bits == 64 ? v : v & ((UINT64_C(1) << bits) - 1);
}

/* Decodes n values of d into out (NULL: skipped). */
static int decode(e57_cv *cv, e57_field *d, double *out, size_t n, e57_file *f, rs_err *err)
{
    if (!out) {
        d->bit += (uint64_t)d->bits * n;
        return 0;
    }
    const uint8_t *p = d->buf;
    uint64_t b = d->bit;
    if (d->type == E57_T_FLOAT && d->bits == 64) {
        if (b % 8 == 0)
            memcpy(out, p + b / 8, n * 8);
        else
            for (size_t i = 0; i < n; i++, b += 64) {
                uint64_t v = get_bits(p, b, 64);
                memcpy(&out[i], &v, 8);
            }
    } else if (d->type == E57_T_FLOAT) {
        for (size_t i = 0; i < n; i++, b += 32) {
            uint32_t v = (uint32_t)get_bits(p, b, 32);
            float x;
            memcpy(&x, &v, 4);
            out[i] = x;
        }
    } else {
        uint64_t range = (uint64_t)d->max - (uint64_t)d->min;
        for (size_t i = 0; i < n; i++, b += (uint64_t)d->bits) {
            uint64_t raw = d->bits ? get_bits(p, b, d->bits) : 0;
            if (raw > range)
                return rs_err_set(err, RS_ERR_INPUT, f->name, 0,
                                  "%s: record %llu holds %llu above its range %lld..%lld; the bytestream is damaged",
                                  d->path, (unsigned long long)(cv->done + i), (unsigned long long)raw,
                                  (long long)d->min, (long long)d->max);
            double v = (double)(int64_t)((uint64_t)d->min + raw);
            out[i] = d->type == E57_T_SCALED ? v * d->scale + d->offset : v;
        }
    }
    d->bit += (uint64_t)d->bits * n;
    return 0;
}

/* Records every field's buffered bits can give. */
static uint64_t available(const e57_cv *cv)
{
    uint64_t n = UINT64_MAX;
    for (int k = 0; k < cv->nfields; k++) {
        const e57_field *d = &cv->fields[k];
        if (d->bits == 0) continue;
        uint64_t a = ((uint64_t)d->len * 8 - d->bit) / (uint64_t)d->bits;
        if (a < n) n = a;
    }
    return n;
}

long e57_cv_read(e57_cv *cv, e57_file *f, double *const out[E57_R_NROLES], size_t max, rs_err *err)
{
    size_t n = 0;
    while (n < max && cv->done < cv->records) {
        uint64_t take = available(cv);
        if (take > max - n) take = max - n;
        if (take > cv->records - cv->done) take = cv->records - cv->done;
        if (take == 0) {
            int r = next_packet(cv, f, err);
            if (r < 0) return -1;
            if (r == 0)
                return rs_err_set(err, RS_ERR_INPUT, f->name, 0,
                                  "XML %s: recordCount is %llu, but its section's %llu data packets end after %llu "
                                  "records; the file is truncated or the XML count is wrong",
                                  cv->path, (unsigned long long)cv->records, (unsigned long long)cv->packets,
                                  (unsigned long long)cv->done);
            continue;
        }
        for (int k = 0; k < cv->nfields; k++) {
            e57_field *d = &cv->fields[k];
            double *o = d->role != E57_R_NONE && out[d->role] ? out[d->role] + n : NULL;
            if (decode(cv, d, o, (size_t)take, f, err) != 0) return -1;
        }
        n += (size_t)take;
        cv->done += take;
    }
    return (long)n;
}

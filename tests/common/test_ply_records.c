/* test_ply_records: the streaming PLY calls (rs_ply_write_records, rs_ply_read_records) give the
 * same bytes and values as the whole-file ones, and rs_transport_read built on them checks what it did. */
#include "tests/testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/fileio.h"
#include "common/ply.h"
#include "light/transport.h"

/* More records than one read block (1 MiB / 18 bytes per record) holds, so blocks join. */
#define NBIG   150000
#define NPROPS 4

static const rs_ply_type BIG_TYPES[NPROPS] = {RS_PLY_UINT32, RS_PLY_INT16, RS_PLY_FLOAT32, RS_PLY_FLOAT64};
static const char *const BIG_NAMES[NPROPS] = {"row", "s", "k", "d"};

/* Record k of the big element: values that each type holds exactly after conversion. */
static void big_values(size_t k, double *v)
{
    v[0] = (double)(k / 7);
    v[1] = (double)((long)(k % 60000) - 30000);
    v[2] = (double)(float)(1.0 / (1.0 + (double)k));
    v[3] = sin((double)k) * 1e3;
}

static int big_record(void *ctx, const rs_ply_element *el, size_t k, double *v, rs_err *err)
{
    size_t *fail_at = ctx;
    if (strcmp(el->name, "big") != 0) return 0;
    if (fail_at && k == *fail_at) return rs_err_set(err, RS_ERR_INPUT, "cb", 0, "stopped at record %zu", k);
    big_values(k, v);
    return 0;
}

/* A small stored element, then the big one: stored (values given) or declared (streamed). */
static rs_ply *make_ply(int stored)
{
    rs_ply *ply = rs_ply_new();
    rs_ply_element *a = rs_ply_add_element(ply, "small", 3);
    double xs[3] = {1.5, -2.25, 1e-3};
    assert_non_null(rs_ply_add_scalar(a, "x", RS_PLY_FLOAT32, xs));
    rs_ply_element *b = rs_ply_add_element(ply, "big", NBIG);
    for (int i = 0; i < NPROPS; i++) {
        if (!stored) {
            assert_non_null(rs_ply_declare_scalar(b, BIG_NAMES[i], BIG_TYPES[i]));
            continue;
        }
        rs_ply_prop *p = rs_ply_add_scalar(b, BIG_NAMES[i], BIG_TYPES[i], NULL);
        assert_non_null(p);
    }
    if (stored) {
        double v[NPROPS];
        for (size_t k = 0; k < NBIG; k++) {
            big_values(k, v);
            for (int i = 0; i < NPROPS; i++) b->props[i].data[k] = v[i];
        }
    }
    rs_ply_add_comment(ply, "records test");
    return ply;
}

static void read_bytes(const char *path, char **data, size_t *size)
{
    rs_err err;
    rs_err_clear(&err);
    if (rs_read_file(path, data, size, &err) != 0) fail_msg("%s", err.msg);
}

static void test_write_same_bytes(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("plyrec_w");
    rs_err err;
    rs_err_clear(&err);
    for (int binary = 0; binary <= 1; binary++) {
        rs_ply *stored = make_ply(1), *declared = make_ply(0);
        const char *pa = rs_test_path(dir, "stored.ply"), *pb = rs_test_path(dir, "streamed.ply");
        assert_int_equal(rs_ply_write(stored, pa, binary, &err), 0);
        assert_int_equal(rs_ply_write_records(declared, pb, binary, big_record, NULL, &err), 0);
        char *a, *b;
        size_t na, nb;
        read_bytes(pa, &a, &na);
        read_bytes(pb, &b, &nb);
        assert_true(na > NBIG * 18);
        assert_int_equal(na, nb);
        assert_memory_equal(a, b, na);
        free(a);
        free(b);
        /* A declared element written without a callback has no data: refused, nothing written. */
        remove(pb);
        assert_int_not_equal(rs_ply_write(declared, pb, binary, &err), 0);
        assert_non_null(strstr(err.msg, "no data"));
        FILE *f = fopen(pb, "rb");
        assert_null(f);
        /* A callback failing half way: its message, and no file left behind. */
        size_t stop = NBIG / 2;
        rs_err_clear(&err);
        assert_int_not_equal(rs_ply_write_records(declared, pb, binary, big_record, &stop, &err), 0);
        assert_non_null(strstr(err.msg, "stopped at record 75000"));
        assert_null(fopen(pb, "rb"));
        rs_ply_free(stored);
        rs_ply_free(declared);
    }
    rs_test_rmtree(dir);
}

/* What a records read saw: per element, the count and the values, to compare with rs_ply_read. */
typedef struct {
    const rs_ply *whole;
    size_t seen[4];
    int bad;
} compare_ctx;

static int compare_record(void *ctx, const rs_ply_element *el, size_t k, double *v, rs_err *err)
{
    (void)err;
    compare_ctx *c = ctx;
    const rs_ply_element *w = rs_ply_find_element(c->whole, el->name);
    int e = (int)(w - c->whole->elements);
    if (!w || k != c->seen[e]++ || w->nprops != el->nprops)
        c->bad++;
    else
        for (int i = 0; i < el->nprops; i++)
            if (memcmp(&v[i], &w->props[i].data[k], sizeof *v) != 0) c->bad++;
    return 0;
}

/* Reads path both ways; every scalar record must arrive once, in order, with the same value. */
static void check_read_same(const char *path, int expect_list)
{
    rs_err err;
    rs_err_clear(&err);
    rs_ply *whole = rs_ply_read(path, &err), *head = NULL;
    if (!whole) fail_msg("%s", err.msg);
    compare_ctx c = {whole, {0}, 0};
    if (rs_ply_read_records(path, compare_record, &c, &head, &err) != 0) fail_msg("%s", err.msg);
    assert_int_equal(c.bad, 0);
    assert_non_null(head);
    assert_int_equal(head->nelements, whole->nelements);
    assert_int_equal(head->ncomments, whole->ncomments);
    for (int e = 0; e < whole->nelements; e++) {
        const rs_ply_element *w = &whole->elements[e], *h = &head->elements[e];
        assert_string_equal(h->name, w->name);
        assert_int_equal(h->count, w->count);
        int list = 0;
        for (int i = 0; i < w->nprops; i++) list |= w->props[i].is_list;
        if (list) { /* kept in the header, with its data */
            assert_int_equal(c.seen[e], 0);
            assert_true(expect_list);
            assert_memory_equal(h->props[0].data, w->props[0].data, w->props[0].offsets[w->count] * sizeof(double));
        } else {
            assert_int_equal(c.seen[e], w->count);
            for (int i = 0; i < h->nprops; i++) assert_null(h->props[i].data);
        }
    }
    rs_ply_free(whole);
    rs_ply_free(head);
}

static void test_read_same_values(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("plyrec_r");
    rs_err err;
    rs_err_clear(&err);
    rs_ply *ply = make_ply(1);
    const char *pb = rs_test_path(dir, "binary.ply"), *pa = rs_test_path(dir, "ascii.ply");
    assert_int_equal(rs_ply_write(ply, pb, 1, &err), 0);
    assert_int_equal(rs_ply_write(ply, pa, 0, &err), 0);
    check_read_same(pb, 0);
    check_read_same(pa, 0); /* ascii: read whole, handed over */
    /* A list element (faces) before the scalars: the whole-file way, the list kept. */
    rs_ply *m = rs_ply_new();
    rs_ply_element *v = rs_ply_add_element(m, "vertex", 3);
    double xyz[3] = {0, 1, 2};
    rs_ply_add_scalar(v, "x", RS_PLY_FLOAT32, xyz);
    rs_ply_element *f = rs_ply_add_element(m, "face", 1);
    double tri[3] = {0, 1, 2};
    rs_ply_add_list_fixed(f, "vertex_indices", RS_PLY_UINT8, RS_PLY_INT32, 3, tri);
    rs_ply_element *t = rs_ply_add_element(m, "extra", 2);
    double ex[2] = {7, 8};
    rs_ply_add_scalar(t, "e", RS_PLY_UINT16, ex);
    const char *pl = rs_test_path(dir, "lists.ply");
    assert_int_equal(rs_ply_write(m, pl, 1, &err), 0);
    check_read_same(pl, 1);
    rs_ply_free(m);
    /* Big endian, written by hand: the same values as the reader's own. */
    const char *pe = rs_test_path(dir, "be.ply");
    FILE *fp = fopen(pe, "wb");
    assert_non_null(fp);
    fputs("ply\nformat binary_big_endian 1.0\nelement e 2\nproperty ushort a\nproperty float b\nend_header\n", fp);
    static const unsigned char be[] = {0x01, 0x02, 0x3f, 0xc0, 0x00, 0x00, 0xff, 0xfe, 0xc1, 0x20, 0x00, 0x00};
    fwrite(be, 1, sizeof be, fp);
    fclose(fp);
    check_read_same(pe, 0);
    rs_ply *whole = rs_ply_read(pe, &err);
    assert_non_null(whole);
    assert_true(whole->elements[0].props[0].data[0] == 258 && whole->elements[0].props[1].data[0] == 1.5);
    assert_true(whole->elements[0].props[0].data[1] == 65534 && whole->elements[0].props[1].data[1] == -10);
    rs_ply_free(whole);
    rs_ply_free(ply);
    rs_test_rmtree(dir);
}

/* A truncated or bad file fails with rs_ply_read's message; a callback's failure stops the read. */
static void test_read_errors(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("plyrec_e");
    rs_err err;
    rs_err_clear(&err);
    rs_ply *ply = make_ply(1);
    const char *pb = rs_test_path(dir, "binary.ply"), *pt = rs_test_path(dir, "cut.ply");
    assert_int_equal(rs_ply_write(ply, pb, 1, &err), 0);
    char *data;
    size_t size;
    read_bytes(pb, &data, &size);
    /* Cut inside a record's third property, and between records. */
    size_t cuts[] = {size - 5, size - 18 * 1000, size - 18 * 70000 - 7};
    for (size_t c = 0; c < sizeof cuts / sizeof *cuts; c++) {
        FILE *f = fopen(pt, "wb");
        fwrite(data, 1, cuts[c], f);
        fclose(f);
        rs_err e1, e2;
        rs_err_clear(&e1);
        rs_err_clear(&e2);
        assert_null(rs_ply_read(pt, &e1));
        assert_int_not_equal(rs_ply_read_records(pt, big_record, NULL, NULL, &e2), 0);
        assert_string_equal(e1.msg, e2.msg);
        assert_non_null(strstr(e2.msg, "truncated"));
    }
    /* A header that is not PLY: the whole-file reader's message. */
    rs_test_write(pt, "plx\nformat ascii 1.0\nend_header\n");
    assert_int_not_equal(rs_ply_read_records(pt, big_record, NULL, NULL, &err), 0);
    assert_non_null(strstr(err.msg, "not a PLY file"));
    /* The callback stops the read with its own message. */
    size_t stop = 60000;
    rs_ply *head = NULL;
    rs_err_clear(&err);
    assert_int_not_equal(rs_ply_read_records(pb, big_record, &stop, &head, &err), 0);
    assert_null(head);
    assert_non_null(strstr(err.msg, "stopped at record 60000"));
    free(data);
    rs_ply_free(ply);
    rs_test_rmtree(dir);
}

/* transport.ply as the irradiance stage writes it: rows in order, read back into compressed rows. */
static void write_transport(const char *path, size_t ne, const double *row, const double *col, const double *k,
                            const double *ku, int with_ku)
{
    rs_err err;
    rs_err_clear(&err);
    rs_ply *ply = rs_ply_new();
    rs_ply_element *t = rs_ply_add_element(ply, "transport", ne);
    rs_ply_add_scalar(t, "row", RS_PLY_UINT32, row);
    rs_ply_add_scalar(t, "col", RS_PLY_UINT32, col);
    rs_ply_add_scalar(t, "k", RS_PLY_FLOAT32, k);
    if (with_ku) rs_ply_add_scalar(t, "k_unseen", RS_PLY_FLOAT32, ku);
    assert_int_equal(rs_ply_write(ply, path, 1, &err), 0);
    rs_ply_free(ply);
}

static void test_transport_read(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("plyrec_t");
    const char *p = rs_test_path(dir, "transport.ply");
    rs_err err;
    rs_err_clear(&err);
    /* Facets 0 and 3 have rows, 1, 2 and 4 none. */
    double row[] = {0, 0, 3, 3, 3}, col[] = {1, 4, 0, 1, 2}, k[] = {0.5, 0.25, 1, 0.125, 2},
           ku[] = {0, 0.25, 0.5, 0, 1};
    write_transport(p, 5, row, col, k, ku, 1);
    rs_transport *t = rs_transport_read(p, 5, &err);
    if (!t) fail_msg("%s", err.msg);
    assert_int_equal(t->nentries, 5);
    size_t rs[] = {0, 2, 2, 2, 5, 5};
    for (int f = 0; f <= 5; f++) assert_int_equal(t->row_start[f], rs[f]);
    for (int e = 0; e < 5; e++) {
        assert_int_equal(t->col[e], (uint32_t)col[e]);
        assert_true(t->k[e] == (float)k[e] && t->k_unseen[e] == (float)ku[e]);
    }
    rs_transport_free(t);
    /* Rows out of order, a column past the facets, a missing property, an empty kernel. */
    double back[] = {3, 0, 3, 3, 3};
    write_transport(p, 5, back, col, k, ku, 1);
    assert_null(rs_transport_read(p, 5, &err));
    assert_non_null(strstr(err.msg, "entry 1: row 0, col 4: expected indices below 5 with rows in order"));
    write_transport(p, 5, row, col, k, ku, 1);
    assert_null(rs_transport_read(p, 4, &err));
    assert_non_null(strstr(err.msg, "entry 1: row 0, col 4: expected indices below 4"));
    write_transport(p, 5, row, col, k, ku, 0);
    assert_null(rs_transport_read(p, 5, &err));
    assert_non_null(strstr(err.msg, "expected element 'transport' with properties row, col, k, k_unseen"));
    write_transport(p, 0, NULL, NULL, NULL, NULL, 0);
    assert_null(rs_transport_read(p, 5, &err));
    write_transport(p, 0, NULL, NULL, NULL, NULL, 1);
    t = rs_transport_read(p, 5, &err);
    assert_non_null(t);
    assert_int_equal(t->nentries, 0);
    assert_int_equal(t->row_start[5], 0);
    rs_transport_free(t);
    double neg[] = {0.5, -0.25, 1, 0.125, 2};
    write_transport(p, 5, row, col, neg, ku, 1);
    assert_null(rs_transport_read(p, 5, &err));
    assert_non_null(strstr(err.msg, "entry 1: weights must be finite and >= 0"));
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_write_same_bytes), cmocka_unit_test(test_read_same_values),
             cmocka_unit_test(test_read_errors), cmocka_unit_test(test_transport_read))

/* test_simplify: quadric edge collapse on exact shapes: an L-shaped block (sharp convex and
 * concave edges, corners, volume, closedness) and a flat open square (boundary kept). */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/mesh.h"
#include "meshing/simplify.h"

/* The L: the union of two boxes, both 2 m high. */
static const double box_lo[2][3] = {{0, 0, 0}, {0, 0, 0}};
static const double box_hi[2][3] = {{4, 1, 2}, {1, 4, 2}};
#define L_VOLUME (2.0 * (4.0 + 3.0))
#define L_SIZE   4.0

static int inside_l(int i, int j, int k, double h)
{
    double p[3] = {(i + 0.5) * h, (j + 0.5) * h, (k + 0.5) * h};
    for (int b = 0; b < 2; b++)
        if (p[0] > box_lo[b][0] && p[0] < box_hi[b][0] && p[1] > box_lo[b][1] && p[1] < box_hi[b][1] &&
            p[2] > box_lo[b][2] && p[2] < box_hi[b][2])
            return 1;
    return 0;
}

/* The closed surface of the L from a voxel lattice of spacing h: each cube face between an
 * inside and an outside cell becomes two triangles wound counter-clockwise from outside;
 * lattice points are shared, so the mesh is closed and manifold. */
static rs_mesh *make_l(double h)
{
    int n[3] = {(int)lround(4 / h), (int)lround(4 / h), (int)lround(2 / h)};
    size_t npts = (size_t)(n[0] + 1) * (n[1] + 1) * (n[2] + 1);
    uint32_t *id = malloc(npts * sizeof *id);
    for (size_t i = 0; i < npts; i++) id[i] = UINT32_MAX;
    size_t cap = 1 << 16, nt = 0, nv = 0;
    uint32_t *tris = malloc(cap * 3 * sizeof *tris);
    float *verts = malloc(npts * 3 * sizeof *verts);
    for (int k = 0; k < n[2]; k++)
        for (int j = 0; j < n[1]; j++)
            for (int i = 0; i < n[0]; i++) {
                if (!inside_l(i, j, k, h)) continue;
                int c[3] = {i, j, k};
                for (int a = 0; a < 3; a++)
                    for (int s = -1; s <= 1; s += 2) {
                        int nb[3] = {i, j, k};
                        nb[a] += s;
                        if (nb[a] >= 0 && nb[a] < n[a] && inside_l(nb[0], nb[1], nb[2], h)) continue;
                        int u = (a + 1) % 3, v = (a + 2) % 3;
                        int base[3] = {c[0], c[1], c[2]};
                        if (s > 0) base[a]++;
                        int du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
                        uint32_t q[4];
                        for (int corner = 0; corner < 4; corner++) {
                            int p[3] = {base[0], base[1], base[2]};
                            p[u] += du[corner];
                            p[v] += dv[corner];
                            size_t key =
                                (size_t)p[0] + (size_t)(n[0] + 1) * ((size_t)p[1] + (size_t)(n[1] + 1) * (size_t)p[2]);
                            if (id[key] == UINT32_MAX) {
                                for (int d = 0; d < 3; d++) verts[3 * nv + d] = (float)(p[d] * h);
                                id[key] = (uint32_t)nv++;
                            }
                            q[corner] = id[key];
                        }
                        if (nt + 2 > cap) {
                            cap *= 2;
                            tris = realloc(tris, cap * 3 * sizeof *tris);
                        }
                        /* (0, u, u+v, v) turns about +a; reversed for the -a side. */
                        uint32_t order[2][4] = {{q[0], q[1], q[2], q[3]}, {q[0], q[3], q[2], q[1]}};
                        const uint32_t *o = order[s < 0];
                        uint32_t t2[6] = {o[0], o[1], o[2], o[0], o[2], o[3]};
                        memcpy(tris + 3 * nt, t2, sizeof t2);
                        nt += 2;
                    }
            }
    rs_mesh *m = rs_mesh_new(nv, nt);
    memcpy(m->verts, verts, nv * 3 * sizeof *verts);
    memcpy(m->tris, tris, nt * 3 * sizeof *tris);
    free(id);
    free(tris);
    free(verts);
    return m;
}

/* Distance from p to the surface of the L (union of two boxes; exact on and near it). */
static double dist_to_l(rs_v3 p)
{
    const double q[3] = {p.x, p.y, p.z};
    double sdf = 1e300;
    for (int b = 0; b < 2; b++) {
        double out2 = 0, in = -1e300;
        for (int j = 0; j < 3; j++) {
            double d = fmax(box_lo[b][j] - q[j], q[j] - box_hi[b][j]);
            if (d > 0) out2 += d * d;
            in = fmax(in, d);
        }
        double box_sdf = out2 > 0 ? sqrt(out2) : in;
        sdf = fmin(sdf, box_sdf);
    }
    return fabs(sdf);
}

static double volume(const rs_mesh *m)
{
    double v = 0;
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 a = rs_mesh_vert(m, m->tris[3 * f]), b = rs_mesh_vert(m, m->tris[3 * f + 1]),
              c = rs_mesh_vert(m, m->tris[3 * f + 2]);
        v += rs_v3_dot(a, rs_v3_cross(b, c)) / 6.0;
    }
    return v;
}

static double mean_edge(const rs_mesh *m)
{
    size_t n;
    double *len = rs_mesh_edge_lengths(m, &n), sum = 0;
    for (size_t i = 0; i < n; i++) sum += len[i];
    free(len);
    return n ? sum / (double)n : 0;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* Closed and manifold with consistent winding: each directed edge once, its reverse once. */
static void assert_closed_manifold(const rs_mesh *m)
{
    size_t n = 3 * m->nfaces;
    uint64_t *e = malloc(n * sizeof *e);
    for (size_t f = 0; f < m->nfaces; f++)
        for (int j = 0; j < 3; j++) e[3 * f + j] = (uint64_t)m->tris[3 * f + j] << 32 | m->tris[3 * f + (j + 1) % 3];
    qsort(e, n, sizeof *e, cmp_u64);
    for (size_t i = 0; i + 1 < n; i++)
        if (e[i] == e[i + 1])
            fail_msg("directed edge %llu -> %llu twice", (unsigned long long)(e[i] >> 32),
                     (unsigned long long)(e[i] & 0xffffffffu));
    for (size_t i = 0; i < n; i++) {
        uint64_t rev = (e[i] & 0xffffffffu) << 32 | e[i] >> 32;
        if (!bsearch(&rev, e, n, sizeof *e, cmp_u64))
            fail_msg("edge %llu -> %llu has no twin: a hole or a flipped face", (unsigned long long)(e[i] >> 32),
                     (unsigned long long)(e[i] & 0xffffffffu));
    }
    free(e);
}

static void test_l_block(void **state)
{
    (void)state;
    rs_mesh *dense = make_l(0.05);
    assert_int_equal(dense->nfaces, 2 * (size_t)(2 * 7 / 0.0025 + 16 * 2 / 0.0025 + 0.5));
    assert_closed_manifold(dense);
    assert_float_equal(volume(dense), L_VOLUME, 1e-3);

    rs_simplify_opts o;
    rs_simplify_defaults(&o);
    o.target_edge_m = 0.3;
    rs_simplify_stats st;
    rs_err err = {0};
    rs_mesh *m = rs_simplify_apply(dense, &o, &st, &err);
    if (!m) fail_msg("%s", err.msg);
    print_message("L block: %zu -> %zu faces, mean edge %.4f m (tracked %.4f), volume %.5f m^3\n", st.faces_in,
                  st.faces_out, mean_edge(m), st.mean_edge_out, volume(m));

    /* The target mean edge length, within 15 %. */
    double me = mean_edge(m);
    assert_true(me >= 0.3 * 0.99 && me <= 0.3 * 1.15);
    assert_float_equal(st.mean_edge_out, me, 1e-6 * me);
    assert_closed_manifold(m);

    /* Every vertex on the surface, within 1 % of the size (in fact much closer). */
    double worst = 0;
    for (size_t v = 0; v < m->nverts; v++) worst = fmax(worst, dist_to_l(rs_mesh_vert(m, (uint32_t)v)));
    print_message("L block: farthest vertex %.2e m from the surface\n", worst);
    assert_true(worst < 0.01 * L_SIZE);
    assert_true(worst < 1e-3);
    assert_float_equal(volume(m), L_VOLUME, 0.01 * L_VOLUME);

    /* The twelve corners, the two ends of the concave edge included, are still vertices. */
    const double corners_xy[6][2] = {{0, 0}, {4, 0}, {4, 1}, {1, 1}, {1, 4}, {0, 4}};
    for (int c = 0; c < 12; c++) {
        rs_v3 want = rs_v3_make(corners_xy[c % 6][0], corners_xy[c % 6][1], c < 6 ? 0 : 2);
        double best = 1e300;
        for (size_t v = 0; v < m->nverts; v++)
            best = fmin(best, rs_v3_len(rs_v3_sub(rs_mesh_vert(m, (uint32_t)v), want)));
        if (best > 1e-3) fail_msg("corner (%g, %g, %g): nearest vertex %.4f m away", want.x, want.y, want.z, best);
    }
    /* Sharp edges kept: no facet bends across an edge of the block, so every normal is
     * (nearly) one of the six axis directions. */
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 n;
        double area;
        rs_mesh_face(m, f, NULL, &n, &area);
        double axis = fmax(fabs(n.x), fmax(fabs(n.y), fabs(n.z)));
        if (axis < cos(1.0 * M_PI / 180))
            fail_msg("face %zu: normal (%.3f, %.3f, %.3f) is off the axes", f, n.x, n.y, n.z);
    }

    /* Deterministic: the same input gives the same mesh. */
    rs_mesh *again = rs_simplify_apply(dense, &o, NULL, &err);
    assert_int_equal(again->nverts, m->nverts);
    assert_int_equal(again->nfaces, m->nfaces);
    assert_memory_equal(again->verts, m->verts, 3 * m->nverts * sizeof(float));
    assert_memory_equal(again->tris, m->tris, 3 * m->nfaces * sizeof(uint32_t));
    rs_mesh_free(again);

    /* A face-count target instead. */
    rs_simplify_defaults(&o);
    o.target_faces = 400;
    rs_mesh *few = rs_simplify_apply(dense, &o, &st, &err);
    assert_true(few->nfaces <= 400 && few->nfaces >= 390);
    assert_closed_manifold(few);
    assert_float_equal(volume(few), L_VOLUME, 0.01 * L_VOLUME);
    rs_mesh_free(few);
    rs_mesh_free(m);
    rs_mesh_free(dense);
}

/* A flat 2 m square of 40 x 40 cells: an open mesh whose outline must stay where it is. */
static void test_open_square(void **state)
{
    (void)state;
    int n = 40;
    double h = 2.0 / n;
    rs_mesh *sq = rs_mesh_new((size_t)(n + 1) * (n + 1), (size_t)2 * n * n);
    for (int j = 0; j <= n; j++)
        for (int i = 0; i <= n; i++) {
            float *p = sq->verts + 3 * (size_t)(j * (n + 1) + i);
            p[0] = (float)(i * h);
            p[1] = (float)(j * h);
            p[2] = 0;
        }
    size_t t = 0;
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++) {
            uint32_t a = (uint32_t)(j * (n + 1) + i), b = a + 1, c = a + (uint32_t)n + 2, d = a + (uint32_t)n + 1;
            uint32_t tt[6] = {a, b, c, a, c, d};
            memcpy(sq->tris + 3 * t, tt, sizeof tt);
            t += 2;
        }
    rs_simplify_opts o;
    rs_simplify_defaults(&o);
    o.target_edge_m = 0.3;
    rs_err err = {0};
    rs_simplify_stats st;
    rs_mesh *m = rs_simplify_apply(sq, &o, &st, &err);
    if (!m) fail_msg("%s", err.msg);
    double area = 0;
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 nrm;
        double a;
        rs_mesh_face(m, f, NULL, &nrm, &a);
        area += a;
        assert_true(nrm.z > 0.999); /* no face turned over */
    }
    print_message("square: %zu -> %zu faces, area %.5f m^2, mean edge %.3f m\n", st.faces_in, st.faces_out, area,
                  mean_edge(m));
    assert_float_equal(area, 4.0, 4e-3);
    for (size_t v = 0; v < m->nverts; v++) {
        const float *p = m->verts + 3 * v;
        assert_true(p[0] >= -1e-6 && p[0] <= 2 + 1e-6 && p[1] >= -1e-6 && p[1] <= 2 + 1e-6 && p[2] == 0);
    }
    double me = mean_edge(m);
    assert_true(me >= 0.3 * 0.99 && me <= 0.3 * 1.15);
    rs_mesh_free(m);
    rs_mesh_free(sq);
}

/* Nothing to do: a mesh already coarser than the target comes back unchanged; degenerate
 * faces (repeated corners) are dropped. */
static void test_trivial(void **state)
{
    (void)state;
    rs_mesh *m = rs_mesh_new(4, 3);
    const float v[12] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0};
    const uint32_t t[9] = {0, 1, 2, 0, 2, 3, 1, 1, 2};
    memcpy(m->verts, v, sizeof v);
    memcpy(m->tris, t, sizeof t);
    rs_simplify_opts o;
    rs_simplify_defaults(&o);
    o.target_edge_m = 0.1;
    rs_err err = {0};
    rs_mesh *out = rs_simplify_apply(m, &o, NULL, &err);
    assert_non_null(out);
    assert_int_equal(out->nfaces, 2);
    assert_int_equal(out->nverts, 4);
    assert_memory_equal(out->tris, t, 6 * sizeof(uint32_t));
    rs_mesh_free(out);
    /* A lone pair of triangles cannot shrink further, whatever the target. */
    o.target_edge_m = 100;
    out = rs_simplify_apply(m, &o, NULL, &err);
    assert_non_null(out);
    assert_true(out->nfaces >= 1);
    rs_mesh_free(out);
    rs_mesh_free(m);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_l_block), cmocka_unit_test(test_open_square),
             cmocka_unit_test(test_trivial))

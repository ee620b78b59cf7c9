/* test_ingest_tiles: the streaming path's cleaning in tiles (stages/ingest/ingest_tiles.c) gives
 * the whole-cloud path's cloud.ply ([ingest] streaming = false). The cloud: two planes of points
 * on a 0.125 m lattice (so that many lie exactly on cell and tile boundaries, which are at
 * powers of two, and on voxel faces), jittered points beside them, and isolated outliers far
 * from everything (their neighbours lie beyond any tile's margin: the fallback). With outlier
 * removal alone the file is byte for byte the whole-cloud path's, for tiles of 16, 100 and 1000
 * points and the default; with a voxel grid too the same voxels come out (the tiles' order),
 * their centroids within float rounding of the whole-cloud path's, their colour within 1. */
#include "tests/testutil.h"
#include "tests/laswrite.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/cloud_ply.h"

static void ingest(const char *dir, const char *work, const char *sets, const char *env)
{
    char cmd[8192], *out = NULL;
    snprintf(cmd, sizeof cmd,
             "%s '%s/rhoscan' ingest '%s/configs/two_planes.ini' --set 'pipeline.workdir=%s/%s' "
             "--set 'ingest.scan=%s/c.las' --set ingest.outlier_neighbours=8 %s",
             env, rs_test_bin_dir(), rs_test_source_dir(), dir, work, dir, sets);
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) fail_msg("exit %d: %s", rc, out);
    free(out);
}

static char *slurp(const char *path, size_t *n)
{
    FILE *f = fopen(path, "rb");
    if (!f) return NULL;
    fseek(f, 0, SEEK_END);
    long len = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *b = malloc((size_t)len + 1);
    *n = fread(b, 1, (size_t)len, f);
    fclose(f);
    return b;
}

static void write_cloud(const char *dir, size_t *total)
{
    enum { N = 6000 };
    double *xyz = malloc(N * 3 * sizeof *xyz);
    uint16_t *rgb = malloc(N * 3 * sizeof *rgb), *in = malloc(N * sizeof *in);
    uint8_t *cls = malloc(N);
    unsigned long long st = 12345;
    size_t n = 0;
    for (int k = 0; k < N; k++) {
        double *p = xyz + 3 * n;
        st = st * 6364136223846793005ULL + 1442695040888963407ULL;
        double u = (double)(st >> 11) / 9007199254740992.0;
        if (k < 2500) { /* the lattice plane z = 0 (points on tile boundaries) */
            p[0] = (k % 50) * 0.125, p[1] = (k / 50) * 0.125, p[2] = 0;
        } else if (k < 5000) { /* a wall x = 2, jittered */
            int q = k - 2500;
            p[0] = 2 + 0.01 * (u - 0.5), p[1] = (q % 50) * 0.125 + 0.03 * u, p[2] = (q / 50) * 0.125;
        } else if (k < 5990) { /* a noisy band above the plane */
            p[0] = 6 * u, p[1] = fmod(k * 0.37, 6), p[2] = 0.05 + 0.2 * fmod(k * 0.61, 1);
        } else { /* isolated outliers, far from everything */
            p[0] = 3 + (k - 5990), p[1] = 20 + 3 * (k - 5990), p[2] = 15;
        }
        for (int j = 0; j < 3; j++) rgb[3 * n + j] = (uint16_t)((k * 7 + j * 50) % 256);
        in[n] = (uint16_t)(k % 1000), cls[n] = 2, n++;
    }
    las_spec s = {.minor = 2, .format = 3, .scale = {1e-4, 1e-4, 1e-4}, .offset = {0, 0, 0}};
    assert_int_equal(las_write(rs_test_path(dir, "c.las"), &s, n, xyz, in, rgb, cls), 0);
    *total = n;
    free(xyz), free(rgb), free(in), free(cls);
}

static void same_bytes(const char *a, const char *b)
{
    size_t na, nb;
    char *x = slurp(a, &na), *y = slurp(b, &nb);
    assert_non_null(x);
    assert_non_null(y);
    if (na != nb || memcmp(x, y, na) != 0) fail_msg("%s and %s differ (%zu and %zu bytes)", a, b, na, nb);
    free(x), free(y);
}

static void test_outliers_same_bytes(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("ingtiles");
    size_t n;
    write_cloud(dir, &n);
    ingest(dir, "whole", "--set ingest.streaming=false", "");
    char a[4096], b[4096];
    snprintf(a, sizeof a, "%s/whole/cloud.ply", dir);
    rs_err err = {0};
    rs_cloud *w = rs_cloud_read_ply(a, &err);
    assert_non_null(w);
    print_message("whole cloud: %zu of %zu points kept\n", w->npoints, n);
    assert_true(w->npoints < n && w->npoints > n - 100); /* the outliers went, not the surfaces */
    rs_cloud_free(w);
    const char *budgets[] = {"16", "100", "1000", ""};
    for (int i = 0; i < 4; i++) {
        char env[128], work[64];
        snprintf(env, sizeof env, "RHOSCAN_INGEST_TILE_POINTS=%s", budgets[i]);
        snprintf(work, sizeof work, "tiles%d", i);
        ingest(dir, work, "", env);
        snprintf(b, sizeof b, "%s/%s/cloud.ply", dir, work);
        same_bytes(a, b);
    }
    rs_test_rmtree(dir);
}

static int cmp_xyz(const void *a, const void *b)
{
    const double *p = a, *q = b;
    for (int j = 0; j < 3; j++)
        if (p[j] != q[j]) return p[j] < q[j] ? -1 : 1;
    return 0;
}

/* The points of c as (voxel key, x, y, z, intensity, r, g, b) rows sorted by voxel. */
static double *rows(const rs_cloud *c, double leaf)
{
    double *r = malloc(c->npoints * 10 * sizeof *r);
    for (size_t i = 0; i < c->npoints; i++) {
        for (int j = 0; j < 3; j++) {
            r[10 * i + j] = floor(c->xyz[3 * i + j] / leaf);
            r[10 * i + 3 + j] = c->xyz[3 * i + j];
            r[10 * i + 7 + j] = c->rgb ? c->rgb[3 * i + j] : 0;
        }
        r[10 * i + 6] = c->intensity ? c->intensity[i] : 0;
    }
    qsort(r, c->npoints, 10 * sizeof *r, cmp_xyz);
    return r;
}

static void test_voxel_same_voxels(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("ingtilesv");
    size_t n;
    write_cloud(dir, &n);
    ingest(dir, "whole", "--set ingest.streaming=false --set ingest.voxel_size=0.25", "");
    char a[4096], b[4096];
    snprintf(a, sizeof a, "%s/whole/cloud.ply", dir);
    rs_err err = {0};
    rs_cloud *w = rs_cloud_read_ply(a, &err);
    assert_non_null(w);
    double *rw = rows(w, 0.25);
    const char *budgets[] = {"16", "100", "1000", ""};
    for (int i = 0; i < 4; i++) {
        char env[128], work[64];
        snprintf(env, sizeof env, "RHOSCAN_INGEST_TILE_POINTS=%s", budgets[i]);
        snprintf(work, sizeof work, "tiles%d", i);
        ingest(dir, work, "--set ingest.voxel_size=0.25", env);
        snprintf(b, sizeof b, "%s/%s/cloud.ply", dir, work);
        rs_cloud *t = rs_cloud_read_ply(b, &err);
        assert_non_null(t);
        assert_int_equal(t->npoints, w->npoints);
        double *rt = rows(t, 0.25), dx = 0, dc = 0, di = 0;
        for (size_t k = 0; k < t->npoints; k++) {
            for (int j = 0; j < 3; j++) {
                assert_true(rt[10 * k + j] == rw[10 * k + j]); /* the same voxels */
                dx = fmax(dx, fabs(rt[10 * k + 3 + j] - rw[10 * k + 3 + j]));
                dc = fmax(dc, fabs(rt[10 * k + 7 + j] - rw[10 * k + 7 + j]));
            }
            di = fmax(di, fabs(rt[10 * k + 6] - rw[10 * k + 6]));
        }
        print_message("tiles of %s points: %zu voxels; centroids within %.3g m, intensity %.3g, colour %.0f\n",
                      *budgets[i] ? budgets[i] : "default", t->npoints, dx, di, dc);
        assert_true(dx <= 2e-6);
        assert_true(di <= 1e-3);
        assert_true(dc <= 1);
        free(rt);
        rs_cloud_free(t);
    }
    free(rw);
    rs_cloud_free(w);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_outliers_same_bytes), cmocka_unit_test(test_voxel_same_voxels))

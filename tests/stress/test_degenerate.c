/* test_degenerate: the sample scene's true geometry plus the facets survey meshes come with:
 * zero-area and sliver triangles, duplicate vertices, a plate with flipped normals, a
 * non-manifold edge, a sealed cavity (no light at all) and a facet seen edge-on. `rhoscan run`
 * must finish; every number it writes is finite, and the facets with nothing to measure are
 * flagged estimable = 0 instead of estimated. */
#include "tests/testutil.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/faceprop.h"
#include "common/image.h"
#include "common/mesh.h"

enum { ZERO_AREA, DUPLICATE, SLIVER, FLIPPED, FIN, SEALED, EDGE_ON, NKINDS };
static const char *kind_name[NKINDS] = {"zero-area",        "duplicate vertices", "sliver", "flipped plate",
                                        "non-manifold fin", "sealed cavity",      "edge-on"};

/* Appends the bad facets to the truth mesh; first[k] is kind k's first face, count[k] its faces. */
static rs_mesh *bad_mesh(const rs_mesh *truth, size_t *first, size_t *count)
{
    static const float v[][3] = {
        {1, 1, 0.001f},                                             /* 0 zero area */
        {1, 2, 0.001f},   {1, 2, 0.001f},   {2, 2, 0.001f},         /* 1-3 duplicates */
        {-2, 0, 0.001f},  {-1, 0, 0.001f},  {-1.5f, 1e-7f, 0.001f}, /* 4-6 sliver */
        {-3, -2, 0.5f},   {-2, -2, 0.5f},   {-2, -1, 0.5f},
        {-3, -1, 0.5f}, /* 7-10 plate */
        {2, -2, 0},       {3, -2, 0},       {2.5f, -2, 1},
        {2.5f, -2.5f, 1}, {2.5f, -1.5f, 1}, /* 11-15 fins */
        {0, 0, -2},       {1, 0, -2},       {0, 1, -2},
        {0, 0, -1},                                        /* 16-19 tetrahedron */
        {0, -3, 0.001f},  {0, -2, 0.001f},  {0, -2.5f, 1}, /* 20-22 edge-on */
    };
    static const uint32_t t[][3] = {
        {0, 0, 0},    {1, 2, 3},    {4, 5, 6},    {7, 9, 8},    {7, 10, 9}, /* normal -z: faces the floor */
        {11, 12, 13}, {12, 11, 14}, {11, 12, 15},                           /* three faces on edge 11-12 */
        {16, 17, 18}, {16, 19, 17}, {16, 18, 19}, {17, 19, 18},             /* normals inward */
        {20, 21, 22},
    };
    static const int kind_of[] = {ZERO_AREA, DUPLICATE, SLIVER, FLIPPED, FLIPPED, FIN,    FIN,
                                  FIN,       SEALED,    SEALED, SEALED,  SEALED,  EDGE_ON};
    size_t nv = sizeof v / sizeof *v, nt = sizeof t / sizeof *t;
    rs_mesh *m = rs_mesh_new(truth->nverts + nv, truth->nfaces + nt);
    memcpy(m->verts, truth->verts, 3 * truth->nverts * sizeof *m->verts);
    memcpy(m->tris, truth->tris, 3 * truth->nfaces * sizeof *m->tris);
    memcpy(m->verts + 3 * truth->nverts, v, sizeof v);
    for (int k = 0; k < NKINDS; k++) count[k] = 0;
    for (size_t f = 0; f < nt; f++) {
        for (int c = 0; c < 3; c++) m->tris[3 * (truth->nfaces + f) + c] = (uint32_t)truth->nverts + t[f][c];
        if (!count[kind_of[f]]++) first[kind_of[f]] = truth->nfaces + f;
    }
    return m;
}

static void assert_ply_finite(const char *path)
{
    rs_err err;
    rs_ply *ply = rs_ply_read(path, &err);
    if (!ply) fail_msg("%s", err.msg);
    for (int e = 0; e < ply->nelements; e++)
        for (int p = 0; p < ply->elements[e].nprops; p++) {
            const rs_ply_prop *pr = &ply->elements[e].props[p];
            size_t n = pr->is_list ? pr->offsets[ply->elements[e].count] : ply->elements[e].count;
            for (size_t k = 0; k < n; k++)
                if (!isfinite(pr->data[k]))
                    fail_msg("%s: %s.%s[%zu] is not finite", path, ply->elements[e].name, pr->name, k);
        }
    rs_ply_free(ply);
}

/* The face of out whose corners are those of face f of in (same order up to rotation), or
 * SIZE_MAX. */
static size_t find_face(const rs_mesh *out, const rs_mesh *in, size_t f)
{
    for (size_t g = 0; g < out->nfaces; g++)
        for (int r = 0; r < 3; r++) {
            int same = 1;
            for (int c = 0; c < 3 && same; c++) {
                const float *a = in->verts + 3 * (size_t)in->tris[3 * f + c];
                const float *b = out->verts + 3 * (size_t)out->tris[3 * g + (c + r) % 3];
                same = a[0] == b[0] && a[1] == b[1] && a[2] == b[2];
            }
            if (same) return g;
        }
    return SIZE_MAX;
}

static void test_bad_facets_flagged_never_nan(void **state)
{
    const char *tmp = rs_test_tmpdir("degenerate");
    char path[4096], cmd[8192];
    rs_err err;
    snprintf(path, sizeof path, "%s/sample_data/two_planes/truth.ply", rs_test_source_dir());
    rs_mesh *truth = rs_mesh_read(path, NULL, &err);
    if (!truth) fail_msg("%s", err.msg);
    size_t first[NKINDS], count[NKINDS];
    rs_mesh *m = bad_mesh(truth, first, count);
    rs_ply *ply = rs_ply_new();
    rs_mesh_to_ply(m, ply);
    const char *mesh_path = rs_test_path(tmp, "bad.ply");
    if (rs_ply_write(ply, mesh_path, 0, &err) != 0) fail_msg("%s", err.msg);
    rs_ply_free(ply);

    char *out = NULL;
    snprintf(cmd, sizeof cmd,
             "%s/rhoscan run %s/configs/two_planes.ini --set pipeline.workdir=%s/work "
             "--set mesh.input_mesh=%s --set irradiance.samples=64 --set irradiance.sky_samples=64 "
             "--set irradiance.sun_samples=16",
             rs_test_bin_dir(), rs_test_source_dir(), tmp, mesh_path);
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) fail_msg("rhoscan run on the bad mesh: exit %d\n%s", rc, out);
    free(out);

    /* Every PLY and EXR of the work folder holds finite numbers only. */
    static const char *plys[] = {"mesh.ply", "observe.ply", "irradiance.ply", "transport.ply", "albedo.ply"};
    for (size_t k = 0; k < sizeof plys / sizeof *plys; k++) {
        snprintf(path, sizeof path, "%s/work/%s", tmp, plys[k]);
        assert_ply_finite(path);
    }
    static const char *exrs[] = {"irradiance.exr", "albedo.exr", "synth.exr", "diff.exr"};
    for (size_t k = 0; k < sizeof exrs / sizeof *exrs; k++) {
        snprintf(path, sizeof path, "%s/work/%s", tmp, exrs[k]);
        rs_image *img = rs_image_read(path, &err);
        if (!img) fail_msg("%s", err.msg);
        for (size_t i = 0; i < (size_t)img->width * img->height * img->channels; i++)
            if (!isfinite(img->data[i])) fail_msg("%s: pixel value %zu is not finite", path, i);
        rs_image_free(img);
    }

    /* The flags: nothing to measure on the degenerate and the sealed facets. */
    snprintf(path, sizeof path, "%s/work/albedo.ply", tmp);
    rs_mesh *am = NULL;
    rs_ply *alb = NULL;
    am = rs_mesh_read(path, &alb, &err);
    if (!am) fail_msg("%s", err.msg);
    size_t nf = am->nfaces;
    double *est = malloc(nf * sizeof *est), *obs = malloc(nf * sizeof *obs), *rho = malloc(3 * nf * sizeof *rho);
    assert_int_equal(rs_faceprop_get(alb, path, "estimable", nf, est, &err), 0);
    assert_int_equal(rs_faceprop_get(alb, path, "observed", nf, obs, &err), 0);
    assert_int_equal(rs_faceprop_get_rgb(alb, path, "albedo", nf, rho, &err), 0);
    /* The mesh stage may repair (drop) facets: find each input facet in the output by its
     * corners; a facet that is not there was removed. */
    for (int k = 0; k < NKINDS; k++) {
        size_t nest = 0, removed = 0;
        for (size_t f = first[k]; f < first[k] + count[k]; f++) {
            size_t g = find_face(am, m, f);
            if (g == SIZE_MAX) {
                removed++;
                continue;
            }
            nest += est[g] != 0;
            if (k == SEALED) assert_true(obs[g] == 0);
        }
        print_message("%-18s %zu facets: %zu removed by the mesh stage, %zu estimable\n", kind_name[k], count[k],
                      removed, nest);
        if (k == ZERO_AREA || k == DUPLICATE || k == SLIVER || k == SEALED) assert_int_equal(nest, 0);
        if (k != ZERO_AREA && k != DUPLICATE) assert_int_equal(removed, 0);
    }
    /* The scene's own facets are still estimated, between 0 and 1. */
    size_t ok = 0;
    for (size_t f = 0; f < truth->nfaces; f++) {
        size_t g = find_face(am, m, f);
        assert_true(g != SIZE_MAX);
        if (!est[g]) continue;
        ok++;
        for (int ch = 0; ch < 3; ch++) assert_true(rho[3 * g + ch] >= 0 && rho[3 * g + ch] <= 1.5);
    }
    print_message("scene facets: %zu of %zu estimable\n", ok, truth->nfaces);
    assert_true(ok >= 2);
    free(est);
    free(obs);
    free(rho);
    rs_ply_free(alb);
    rs_mesh_free(am);
    rs_mesh_free(m);
    rs_mesh_free(truth);
    rs_test_rmtree(tmp);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_bad_facets_flagged_never_nan))

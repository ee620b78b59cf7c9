/* stress: helpers the stress tests share (header-only, static): gathering K for every facet,
 * writing a work folder of stage inputs from synthetic quantities, and running a stage. */
#ifndef RS_STRESS_H
#define RS_STRESS_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/faceprop.h"
#include "common/fileio.h"
#include "light/gather.h"
#include "common/mesh.h"
#include "tests/meshgen.h"
#include "common/scene.h"
#include "stages/stages.h"
#include "tests/testutil.h"
#include "light/transport.h"

/* K from the hemisphere gather of every facet with no sky (escaping rays bring nothing), in
 * compressed-row form. Caller frees with stress_transport_free. */
static inline rs_transport *stress_gather_K(const rs_mesh *m, int samples, uint32_t seed)
{
    rs_err err;
    rs_scene *scene = rs_scene_new(m, &err);
    if (!scene) fail_msg("scene: %s", err.msg);
    size_t nf = m->nfaces, ne = 0;
    rs_facet_gather *rows = calloc(nf, sizeof *rows);
    rs_gather_ctx g = {.scene = scene, .samples = samples, .seed = seed};
    int failed = 0;
#pragma omp parallel
    {
        rs_gather_scratch *s = rs_gather_scratch_new((size_t)samples);
#pragma omp for schedule(dynamic, 8) reduction(| : failed)
        for (size_t f = 0; f < nf; f++) failed |= rs_gather_facet(&g, (uint32_t)f, s, &rows[f]) != 0;
        rs_gather_scratch_free(s);
    }
    assert_false(failed);
    for (size_t f = 0; f < nf; f++) ne += rows[f].nentries;
    rs_transport *K = calloc(1, sizeof *K);
    K->nfaces = nf;
    K->nentries = ne;
    K->row_start = calloc(nf + 1, sizeof *K->row_start);
    K->col = malloc((ne + 1) * sizeof *K->col);
    K->k = malloc((ne + 1) * sizeof *K->k);
    K->k_unseen = malloc((ne + 1) * sizeof *K->k_unseen);
    size_t e = 0;
    for (size_t f = 0; f < nf; f++) {
        for (uint32_t q = 0; q < rows[f].nentries; q++, e++) {
            K->col[e] = rows[f].entries[q].col;
            K->k[e] = rows[f].entries[q].k;
            K->k_unseen[e] = rows[f].entries[q].k; /* no camera: every hit goes through K */
        }
        K->row_start[f + 1] = e;
        free(rows[f].entries);
    }
    free(rows);
    rs_scene_free(scene);
    return K;
}

static inline void stress_transport_free(rs_transport *K)
{
    if (!K) return;
    free(K->row_start);
    free(K->col);
    free(K->k);
    free(K->k_unseen);
    free(K);
}

static inline double stress_row_sum(const rs_transport *K, size_t i)
{
    double s = 0;
    for (size_t e = K->row_start[i]; e < K->row_start[i + 1]; e++) s += K->k[e];
    return s;
}

/* A face PLY of the mesh with per-facet rgb properties and float scalars (NULL ends a list). */
static inline void stress_write_faces(const char *path, const rs_mesh *m, const char *const *prefixes,
                                      const double *const *values, const char *const *scalars,
                                      const double *const *svalues)
{
    rs_ply *ply = rs_ply_new();
    rs_ply_element *faces = rs_mesh_to_ply(m, ply);
    for (int k = 0; prefixes && prefixes[k]; k++)
        assert_int_equal(rs_faceprop_add_rgb(faces, prefixes[k], values[k]), 0);
    for (int k = 0; scalars && scalars[k]; k++)
        assert_non_null(rs_ply_add_scalar(faces, scalars[k], RS_PLY_FLOAT32, svalues[k]));
    rs_err err;
    if (rs_ply_write(ply, path, 1, &err) != 0) fail_msg("%s", err.msg);
    rs_ply_free(ply);
}

/* The reflectance stage's inputs in dir: mesh.ply, observe.ply (radiance L, every facet
 * observed unless observed is given), irradiance.ply (E_sky, nothing read from a panorama at
 * hit points) and transport.ply (K). */
static inline void stress_write_reflectance_inputs(const char *dir, const rs_mesh *m, const double *L,
                                                   const double *esky, const double *observed, const rs_transport *K)
{
    size_t nf = m->nfaces;
    rs_err err;
    rs_ply *ply = rs_ply_new();
    rs_mesh_to_ply(m, ply);
    if (rs_ply_write(ply, rs_test_path(dir, "mesh.ply"), 1, &err) != 0) fail_msg("%s", err.msg);
    rs_ply_free(ply);
    double *ones = malloc(nf * sizeof *ones), *zero = calloc(3 * nf, sizeof *zero);
    for (size_t i = 0; i < nf; i++) ones[i] = 1;
    const char *obs_p[] = {"radiance", NULL}, *obs_s[] = {"observed", NULL};
    const double *obs_v[] = {L}, *obs_sv[] = {observed ? observed : ones};
    stress_write_faces(rs_test_path(dir, "observe.ply"), m, obs_p, obs_v, obs_s, obs_sv);
    /* The sky was measured everywhere: nothing filled in, no fill uncertainty. */
    const char *irr_p[] = {"irradiance_sky", "irradiance_inter_seen", NULL};
    const char *irr_s[] = {"sky_filled", "irradiance_sky_sigma", NULL};
    const double *irr_v[] = {esky, zero}, *irr_sv[] = {zero, zero};
    stress_write_faces(rs_test_path(dir, "irradiance.ply"), m, irr_p, irr_v, irr_s, irr_sv);
    ply = rs_ply_new();
    size_t ne = K ? K->nentries : 0;
    double *cols = malloc((4 * ne + 1) * sizeof *cols);
    double *row = cols + ne, *k = cols + 2 * ne, *ku = cols + 3 * ne;
    for (size_t i = 0; K && i < nf; i++)
        for (size_t e = K->row_start[i]; e < K->row_start[i + 1]; e++) {
            row[e] = (double)i;
            cols[e] = K->col[e];
            k[e] = K->k[e];
            ku[e] = K->k_unseen[e];
        }
    rs_ply_element *tr = rs_ply_add_element(ply, "transport", ne);
    rs_ply_add_scalar(tr, "row", RS_PLY_UINT32, row);
    rs_ply_add_scalar(tr, "col", RS_PLY_UINT32, cols);
    rs_ply_add_scalar(tr, "k", RS_PLY_FLOAT32, k);
    rs_ply_add_scalar(tr, "k_unseen", RS_PLY_FLOAT32, ku);
    if (rs_ply_write(ply, rs_test_path(dir, "transport.ply"), 1, &err) != 0) fail_msg("%s", err.msg);
    rs_ply_free(ply);
    free(cols);
    free(ones);
    free(zero);
}

/* Runs one stage on the work folder dir with extra config text (INI, may be ""); returns the
 * stage's status and its error in *err. */
static inline int stress_run_stage(const char *stage, const char *dir, const char *extra, rs_err *err)
{
    char text[8192];
    snprintf(text, sizeof text, "[pipeline]\nworkdir = %s\n%s", dir, extra);
    rs_config *cfg = rs_config_load_string(text, "stress.ini", dir, NULL, err);
    if (!cfg) fail_msg("config: %s", err->msg);
    int rc = rs_stage_execute(rs_stage_find(stage), cfg, NULL, err);
    rs_config_free(cfg);
    return rc;
}

/* albedo.ply's albedo (3 * nf) and estimable (nf) flags; caller frees both. */
static inline void stress_read_albedo(const char *dir, size_t nf, double **albedo, double **estimable)
{
    rs_err err;
    const char *p = rs_test_path(dir, "albedo.ply");
    rs_ply *ply = rs_ply_read(p, &err);
    if (!ply) fail_msg("%s", err.msg);
    *albedo = malloc(3 * nf * sizeof **albedo);
    *estimable = malloc(nf * sizeof **estimable);
    assert_int_equal(rs_faceprop_get_rgb(ply, p, "albedo", nf, *albedo, &err), 0);
    assert_int_equal(rs_faceprop_get(ply, p, "estimable", nf, *estimable, &err), 0);
    rs_ply_free(ply);
}

#endif

/* skysh: the sky map's irradiance for facets that see only sky, from its projection on real
 * spherical harmonics up to order 2 (Ramamoorthi & Hanrahan 2001), used only when the map
 * itself shows it is smooth enough. Exports rs_skysh_* (build with the test, evaluate, exact). */
#ifndef RS_SKYSH_H
#define RS_SKYSH_H

#include <stddef.h>
#include "common/scene.h"
#include "sky/skyenv.h"

/* Channels carried: R, G, B, the luminance of the filled-in pixels (for sky_filled), that
 * luminance times each pixel's fill uncertainty (for irradiance_sky_sigma), and the last times
 * the pixel's world direction x and y (gather.h fill_sigma_dir: signed, never clamped). The
 * frequency test covers the first RS_SKYSH_TESTED; the moments ride on the same order 2,
 * untested (they only weigh the fill's uncertainty by direction). */
enum { RS_SKYSH_CHANNELS = 7, RS_SKYSH_TESTED = 5, RS_SKYSH_COEFS = 9, RS_SKYSH_MAX_NORMALS = 1024 };

/* A facet's error bound is the worst error of the test normals within this angle of its normal
 * (about twice their spacing at 256 normals): the error varies with the normal no faster than
 * the order-4 harmonics it comes from (A_3 = 0), whose features are 45 degrees wide. */
#define RS_SKYSH_NEIGHBOUR_DEG 25.0
/* ... times this: between test normals the error can peak above its neighbours' (by 1.07 x at
 * worst over 3000 random normals on a CIE overcast sky over a dark ground, tests/sky/test_skysh.c). */
#define RS_SKYSH_BOUND_FACTOR 1.5

typedef struct rs_skysh {
    int usable;  /* 1: the test passed at some normals: facets near them may use it */
    double tol;  /* the test's tolerance (relative) */
    int normals; /* test normals (Fibonacci sphere) */
    /* The map outside the sun set, projected: L_lm per channel (radiance x sr). */
    double coef[RS_SKYSH_CHANNELS][RS_SKYSH_COEFS];
    /* The sun set (env->sun), exactly: sum of L d dOmega per channel. Its clamped-cosine
     * integral is n . sun_vec while the whole set lies above the facet's plane, 0 while it lies
     * below: a facet whose plane cuts the set is left to the rays. */
    int has_sun;
    double sun_vec[RS_SKYSH_CHANNELS][3];
    rs_v3 sun_axis; /* unit; the set lies within the cone of this axis ... */
    double sun_sin; /* ... whose half-angle has this sine */
    /* The test, over the map outside the sun set: worst relative error of the projected
     * irradiance against the exact clamped-cosine sum over the map's pixels, R, G and B, with
     * the error taken relative to max(E(n), 1e-3 max_n E) so that normals facing a black
     * part of the map do not decide alone. max_error_filled: the same for the filled
     * luminance, relative to the normal's luminance E (reported, not tested). */
    double max_error, max_error_filled;
    rs_v3 worst_normal;                       /* where max_error was found */
    float error_at[RS_SKYSH_MAX_NORMALS];     /* each test normal's error */
    float normal_at[RS_SKYSH_MAX_NORMALS][3]; /* the test normals (rs_skysh_normal) */
    double passed_share;                      /* share of the sphere of normals whose bound is within tol */
} rs_skysh;

/* Projects env (world frame, its pixels' solid angles) and runs the frequency test over
 * `normals` (<= RS_SKYSH_MAX_NORMALS) Fibonacci normals; sh->usable = tol > 0 and some
 * normal's bound (rs_skysh_bound) is within tol. Returns 0, -1 when out of memory (err set). */
int rs_skysh_build(const rs_skyenv *env, double tol, int normals, rs_skysh *sh, rs_err *err);

/* Irradiance from the projection at unit world normal n: e as the channels above (sun set
 * included). Returns 0 and leaves e alone when n's plane cuts the sun set. */
int rs_skysh_eval(const rs_skysh *sh, rs_v3 n, double e[RS_SKYSH_CHANNELS]);

/* The relative error bound at unit world normal n: the worst error_at over the test normals
 * within RS_SKYSH_NEIGHBOUR_DEG of n, times RS_SKYSH_BOUND_FACTOR. */
double rs_skysh_bound(const rs_skysh *sh, rs_v3 n);

/* For a facet with normal n that sees only sky (the model below its plane): when the bound at n
 * is within tol and n's plane does not cut the sun set, e = the projection's irradiance outside
 * the sun set (the first RS_SKYSH_TESTED channels clamped at 0), es = the sun set's (exact), *bound = the relative error bound of e,
 * and returns 1; else 0 (e, es and bound then mean nothing). */
int rs_skysh_sky_only(const rs_skysh *sh, rs_v3 n, double e[RS_SKYSH_CHANNELS], double es[RS_SKYSH_CHANNELS],
                      double *bound);

/* The exact clamped-cosine sum over every pixel of env at unit world normal n, the sun set
 * included: e[c] = sum L_c max(0, n . d) dOmega (pixel centres). For tests: O(pixels). */
void rs_skysh_exact(const rs_skyenv *env, rs_v3 n, double e[RS_SKYSH_CHANNELS]);

/* Facets with every corner of the model's bounding box below their plane (by more than half
 * the ray offset): the test gather.c's skip_convex applies, counted before the gather so that
 * the projection (0.3 CPU-s on a 2048 x 1024 map) is built only when some facet can use it. */
size_t rs_skysh_candidates(const rs_scene *scene);

/* Test normal k of n: the Fibonacci sphere (unit, world frame). */
rs_v3 rs_skysh_normal(int k, int n);

#endif

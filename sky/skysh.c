/* skysh: order-2 spherical-harmonic irradiance of the sky map for facets that see only sky,
 * with the map's own test of whether order 2 is enough (see skysh.h). */
#include "sky/skysh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/par.h"

/* Real spherical harmonics up to order 2 at unit d (Ramamoorthi & Hanrahan 2001, eq. 3). */
static void sh9(rs_v3 d, double y[RS_SKYSH_COEFS])
{
    y[0] = 0.282095;
    y[1] = 0.488603 * d.y;
    y[2] = 0.488603 * d.z;
    y[3] = 0.488603 * d.x;
    y[4] = 1.092548 * d.x * d.y;
    y[5] = 1.092548 * d.y * d.z;
    y[6] = 0.315392 * (3 * d.z * d.z - 1);
    y[7] = 1.092548 * d.x * d.z;
    y[8] = 0.546274 * (d.x * d.x - d.y * d.y);
}

/* The clamped cosine's harmonic coefficients A_l (Ramamoorthi & Hanrahan 2001, eq. 8): pi,
 * 2 pi / 3, pi / 4; E(n) = sum_lm A_l L_lm Y_lm(n). */
static const double A_L[RS_SKYSH_COEFS] = {M_PI,     2 * M_PI / 3, 2 * M_PI / 3, 2 * M_PI / 3, M_PI / 4,
                                           M_PI / 4, M_PI / 4,     M_PI / 4,     M_PI / 4};

static double lum3(const double *e)
{
    return 0.2126 * e[0] + 0.7152 * e[1] + 0.0722 * e[2];
}

/* A pixel's channels (skysh.h), 0 when not finite; d: its world direction (the moments; the
 * frequency test, which reads the first RS_SKYSH_TESTED alone, passes any). */
static void pixel_values(const rs_skyenv *env, size_t p, rs_v3 d, double v[RS_SKYSH_CHANNELS])
{
    const float *L = env->radiance + 3 * p;
    for (int ch = 0; ch < 3; ch++) v[ch] = isfinite(L[ch]) ? L[ch] : 0;
    v[3] = env->filled && env->filled[p] ? lum3(v) : 0;
    v[4] = env->fill_sigma_px ? v[3] * env->fill_sigma_px[p] : 0; /* gather.h: fill_sigma_lum */
    v[5] = v[4] * d.x;                                             /* gather.h: fill_sigma_dir */
    v[6] = v[4] * d.y;
}

/* The map's pixel directions from per-row and per-column tables (pano.h's convention:
 * phi = pi (1 - 2u), theta = pi v, local frame), and per-row solid angles. */
typedef struct {
    int w, h;
    double *st, *ct, *cp, *sp, *dom;
} grid;

static int grid_new(const rs_skyenv *env, grid *g)
{
    g->w = env->width, g->h = env->height;
    g->st = malloc(((size_t)3 * g->h + 2 * (size_t)g->w) * sizeof *g->st);
    if (!g->st) return -1;
    g->ct = g->st + g->h, g->dom = g->ct + g->h, g->cp = g->dom + g->h, g->sp = g->cp + g->w;
    for (int r = 0; r < g->h; r++) {
        double th = M_PI * (r + 0.5) / g->h;
        g->st[r] = sin(th), g->ct[r] = cos(th);
        g->dom[r] = rs_pano_pixel_solid_angle(g->w, g->h, r);
    }
    for (int c = 0; c < g->w; c++) {
        double ph = M_PI * (1 - 2 * (c + 0.5) / g->w);
        g->cp[c] = cos(ph), g->sp[c] = sin(ph);
    }
    return 0;
}

static inline rs_v3 grid_dir(const grid *g, int c, int r)
{
    return rs_v3_make(g->st[r] * g->cp[c], g->st[r] * g->sp[c], g->ct[r]);
}

/* Blocks of BxB pixels outside the sun set (local frame): sum of L d dOmega per channel, and a
 * cone around their pixel centres. For a normal whose plane misses the cone the exact sum is
 * n . V (all in front) or 0 (all behind); only blocks the plane cuts are summed by pixel. */
enum { BLOCK = 8 };
typedef struct {
    double v[RS_SKYSH_TESTED][3];
    rs_v3 axis;
    double sin_half; /* > 1: the cone is a hemisphere or more, always summed by pixel */
} block;

static void block_build(const rs_skyenv *env, const grid *g, int c0, int r0, block *b)
{
    memset(b, 0, sizeof *b);
    rs_v3 ax = {0, 0, 0};
    int c1 = c0 + BLOCK < g->w ? c0 + BLOCK : g->w, r1 = r0 + BLOCK < g->h ? r0 + BLOCK : g->h;
    for (int r = r0; r < r1; r++)
        for (int c = c0; c < c1; c++) {
            size_t p = (size_t)r * g->w + c;
            rs_v3 d = grid_dir(g, c, r);
            ax = rs_v3_add(ax, rs_v3_scale(d, g->dom[r]));
            if (env->sun[p]) continue;
            double v[RS_SKYSH_CHANNELS];
            pixel_values(env, p, d, v);
            for (int ch = 0; ch < RS_SKYSH_TESTED; ch++) {
                b->v[ch][0] += v[ch] * g->dom[r] * d.x;
                b->v[ch][1] += v[ch] * g->dom[r] * d.y;
                b->v[ch][2] += v[ch] * g->dom[r] * d.z;
            }
        }
    b->axis = rs_v3_norm(ax);
    double mincos = 1;
    for (int r = r0; r < r1; r++)
        for (int c = c0; c < c1; c++) mincos = fmin(mincos, rs_v3_dot(b->axis, grid_dir(g, c, r)));
    b->sin_half = mincos > 0 ? sqrt(1 - mincos * mincos) : 2;
}

/* Exact clamped-cosine sum outside the sun set at local normal n, through the blocks. */
static void exact_blocks(const rs_skyenv *env, const grid *g, const block *bl, int nbc, int nbr, rs_v3 n,
                         double e[RS_SKYSH_CHANNELS])
{
    const double margin = 1e-9;
    memset(e, 0, RS_SKYSH_CHANNELS * sizeof *e);
    for (int br = 0; br < nbr; br++)
        for (int bc = 0; bc < nbc; bc++) {
            const block *b = &bl[(size_t)br * nbc + bc];
            double t = rs_v3_dot(n, b->axis);
            if (t > b->sin_half + margin) {
                for (int ch = 0; ch < RS_SKYSH_TESTED; ch++)
                    e[ch] += n.x * b->v[ch][0] + n.y * b->v[ch][1] + n.z * b->v[ch][2];
                continue;
            }
            if (t < -b->sin_half - margin) continue;
            int c0 = bc * BLOCK, r0 = br * BLOCK;
            int c1 = c0 + BLOCK < g->w ? c0 + BLOCK : g->w, r1 = r0 + BLOCK < g->h ? r0 + BLOCK : g->h;
            for (int r = r0; r < r1; r++)
                for (int c = c0; c < c1; c++) {
                    size_t p = (size_t)r * g->w + c;
                    double cosn = rs_v3_dot(n, grid_dir(g, c, r));
                    if (cosn <= 0 || env->sun[p]) continue;
                    double v[RS_SKYSH_CHANNELS];
                    pixel_values(env, p, grid_dir(g, c, r), v);
                    for (int ch = 0; ch < RS_SKYSH_TESTED; ch++) e[ch] += v[ch] * cosn * g->dom[r];
                }
        }
}

rs_v3 rs_skysh_normal(int k, int n)
{
    double z = 1 - (2.0 * k + 1) / n, rho = sqrt(fmax(0, 1 - z * z));
    double phi = k * M_PI * (3 - sqrt(5.0)); /* the golden angle */
    return rs_v3_make(rho * cos(phi), rho * sin(phi), z);
}

/* Irradiance of the projection alone (sun set not included) at world normal n. */
static void eval_sh(const rs_skysh *sh, rs_v3 n, double e[RS_SKYSH_CHANNELS])
{
    double y[RS_SKYSH_COEFS];
    sh9(n, y);
    for (int ch = 0; ch < RS_SKYSH_CHANNELS; ch++) {
        e[ch] = 0;
        for (int k = 0; k < RS_SKYSH_COEFS; k++) e[ch] += A_L[k] * sh->coef[ch][k] * y[k];
    }
}

int rs_skysh_build(const rs_skyenv *env, double tol, int normals, rs_skysh *sh, rs_err *err)
{
    memset(sh, 0, sizeof *sh);
    if (normals > RS_SKYSH_MAX_NORMALS) normals = RS_SKYSH_MAX_NORMALS;
    sh->tol = tol;
    sh->normals = normals;
    grid g;
    int nbc = (env->width + BLOCK - 1) / BLOCK, nbr = (env->height + BLOCK - 1) / BLOCK;
    block *bl = malloc((size_t)nbc * nbr * sizeof *bl);
    double *ex = malloc((size_t)normals * 2 * RS_SKYSH_CHANNELS * sizeof *ex);
    if (!bl || !ex || grid_new(env, &g) != 0) {
        free(bl);
        free(ex);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory projecting the %dx%d sky map on harmonics",
                          env->width, env->height);
    }
    /* Projection (world frame) and the sun set's exact part. */
    rs_v3 sun_ax = {0, 0, 0};
    for (int r = 0; r < g.h; r++)
        for (int c = 0; c < g.w; c++) {
            size_t p = (size_t)r * g.w + c;
            rs_v3 d = rs_pose_dir_to_world(&env->pose, grid_dir(&g, c, r));
            double v[RS_SKYSH_CHANNELS], y[RS_SKYSH_COEFS];
            pixel_values(env, p, d, v);
            if (env->sun[p]) {
                sh->has_sun = 1;
                sun_ax = rs_v3_add(sun_ax, rs_v3_scale(d, g.dom[r]));
                for (int ch = 0; ch < RS_SKYSH_CHANNELS; ch++) {
                    sh->sun_vec[ch][0] += v[ch] * g.dom[r] * d.x;
                    sh->sun_vec[ch][1] += v[ch] * g.dom[r] * d.y;
                    sh->sun_vec[ch][2] += v[ch] * g.dom[r] * d.z;
                }
                continue;
            }
            sh9(d, y);
            for (int ch = 0; ch < RS_SKYSH_CHANNELS; ch++)
                for (int k = 0; k < RS_SKYSH_COEFS; k++) sh->coef[ch][k] += v[ch] * y[k] * g.dom[r];
        }
    if (sh->has_sun) {
        sh->sun_axis = rs_v3_norm(sun_ax);
        double mincos = 1;
        for (int r = 0; r < g.h; r++)
            for (int c = 0; c < g.w; c++)
                if (env->sun[(size_t)r * g.w + c])
                    mincos =
                        fmin(mincos, rs_v3_dot(sh->sun_axis, rs_pose_dir_to_world(&env->pose, grid_dir(&g, c, r))));
        sh->sun_sin = mincos > 0 ? sqrt(1 - mincos * mincos) : 2;
    }

    /* The frequency test: exact sums (by block) against the projection at each test normal.
     * Rows of blocks and normals are independent: in an MPI run (common/par.h) each rank does
     * its share of both and the ranks exchange them, the same bytes as one process. */
    size_t lo, hi;
    rs_par_range((size_t)nbr, &lo, &hi);
#pragma omp parallel for schedule(dynamic, 1)
    for (int br = (int)lo; br < (int)hi; br++)
        for (int bc = 0; bc < nbc; bc++) block_build(env, &g, bc * BLOCK, br * BLOCK, &bl[(size_t)br * nbc + bc]);
    int shared = rs_par_allgather_range(bl, (size_t)nbr, (size_t)nbc * sizeof *bl, err);
    rs_par_range((size_t)normals, &lo, &hi);
#pragma omp parallel for schedule(dynamic, 4)
    for (int k = (int)lo; k < (int)hi; k++) {
        rs_v3 n = rs_skysh_normal(k, normals);
        exact_blocks(env, &g, bl, nbc, nbr, rs_pose_dir_to_local(&env->pose, n),
                     ex + (size_t)k * 2 * RS_SKYSH_CHANNELS);
        eval_sh(sh, n, ex + ((size_t)k * 2 + 1) * RS_SKYSH_CHANNELS);
    }
    if (shared != 0 || rs_par_allgather_range(ex, (size_t)normals, 2 * RS_SKYSH_CHANNELS * sizeof *ex, err) != 0) {
        free(bl);
        free(ex);
        free(g.st);
        return -1;
    }
    double emax[RS_SKYSH_CHANNELS + 1] = {0};
    for (int k = 0; k < normals; k++) {
        const double *e = ex + (size_t)k * 2 * RS_SKYSH_CHANNELS;
        for (int ch = 0; ch < 3; ch++) emax[ch] = fmax(emax[ch], e[ch]);
        emax[3] = fmax(emax[3], lum3(e));
    }
    for (int k = 0; k < normals; k++) {
        const double *e = ex + (size_t)k * 2 * RS_SKYSH_CHANNELS, *s = e + RS_SKYSH_CHANNELS;
        double worst = 0;
        for (int ch = 0; ch < 3; ch++)
            if (emax[ch] > 0) worst = fmax(worst, fabs(s[ch] - e[ch]) / fmax(e[ch], 1e-3 * emax[ch]));
        sh->error_at[k] = (float)worst;
        rs_v3 nk = rs_skysh_normal(k, normals);
        sh->normal_at[k][0] = (float)nk.x, sh->normal_at[k][1] = (float)nk.y, sh->normal_at[k][2] = (float)nk.z;
        if (worst > sh->max_error) sh->max_error = worst, sh->worst_normal = rs_skysh_normal(k, normals);
        if (emax[3] > 0)
            sh->max_error_filled = fmax(sh->max_error_filled, fabs(s[3] - e[3]) / fmax(lum3(e), 1e-3 * emax[3]));
    }
    size_t passed = 0;
    for (int k = 0; k < normals; k++) passed += rs_skysh_bound(sh, rs_skysh_normal(k, normals)) <= tol;
    sh->passed_share = normals ? (double)passed / normals : 0;
    sh->usable = tol > 0 && passed > 0;
    free(g.st);
    free(bl);
    free(ex);
    return 0;
}

/* The sun set's part at world normal n: 1 and e_sun filled, or 0 when n's plane cuts the set. */
static int eval_sun(const rs_skysh *sh, rs_v3 n, double e_sun[RS_SKYSH_CHANNELS])
{
    memset(e_sun, 0, RS_SKYSH_CHANNELS * sizeof *e_sun);
    if (!sh->has_sun) return 1;
    double t = rs_v3_dot(n, sh->sun_axis);
    if (t < -sh->sun_sin - 1e-9) return 1;
    if (!(t > sh->sun_sin + 1e-9)) return 0;
    for (int ch = 0; ch < RS_SKYSH_CHANNELS; ch++)
        e_sun[ch] = n.x * sh->sun_vec[ch][0] + n.y * sh->sun_vec[ch][1] + n.z * sh->sun_vec[ch][2];
    return 1;
}

int rs_skysh_eval(const rs_skysh *sh, rs_v3 n, double e[RS_SKYSH_CHANNELS])
{
    double es[RS_SKYSH_CHANNELS];
    if (!eval_sun(sh, n, es)) return 0;
    eval_sh(sh, n, e);
    for (int ch = 0; ch < RS_SKYSH_CHANNELS; ch++) e[ch] += es[ch];
    return 1;
}

double rs_skysh_bound(const rs_skysh *sh, rs_v3 n)
{
    double c = cos(RS_SKYSH_NEIGHBOUR_DEG * M_PI / 180), worst = 0;
    for (int k = 0; k < sh->normals; k++)
        if (n.x * sh->normal_at[k][0] + n.y * sh->normal_at[k][1] + n.z * sh->normal_at[k][2] >= c)
            worst = fmax(worst, sh->error_at[k]);
    return RS_SKYSH_BOUND_FACTOR * worst;
}

int rs_skysh_sky_only(const rs_skysh *sh, rs_v3 n, double e[RS_SKYSH_CHANNELS], double es[RS_SKYSH_CHANNELS],
                      double *bound)
{
    if (!sh || !sh->usable || !eval_sun(sh, n, es)) return 0;
    *bound = rs_skysh_bound(sh, n);
    if (!(*bound <= sh->tol)) return 0;
    eval_sh(sh, n, e);
    /* The projection's error is relative to what it carries (the map outside the sun set);
     * the sun set's part is exact. A projection that dips below 0 at this normal is clamped. */
    for (int ch = 0; ch < RS_SKYSH_TESTED; ch++) e[ch] = fmax(0, e[ch]);
    return 1;
}

void rs_skysh_exact(const rs_skyenv *env, rs_v3 n, double e[RS_SKYSH_CHANNELS])
{
    memset(e, 0, RS_SKYSH_CHANNELS * sizeof *e);
    for (int r = 0; r < env->height; r++) {
        double dom = rs_pano_pixel_solid_angle(env->width, env->height, r);
        for (int c = 0; c < env->width; c++) {
            rs_v3 d = rs_pose_dir_to_world(&env->pose, rs_pano_pixel_dir(env->width, env->height, c, r));
            double cosn = rs_v3_dot(n, d), v[RS_SKYSH_CHANNELS];
            if (cosn <= 0) continue;
            pixel_values(env, (size_t)r * env->width + c, d, v);
            for (int ch = 0; ch < RS_SKYSH_CHANNELS; ch++) e[ch] += v[ch] * cosn * dom;
        }
    }
}

size_t rs_skysh_candidates(const rs_scene *scene)
{
    const rs_mesh *m = rs_scene_mesh(scene);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < m->nverts; v++)
        for (int k = 0; k < 3; k++) {
            lo[k] = fmin(lo[k], m->verts[3 * v + k]);
            hi[k] = fmax(hi[k], m->verts[3 * v + k]);
        }
    double eps = 0.5 * rs_scene_offset(scene, rs_v3_make(0, 0, 0));
    size_t n = 0;
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 nrm = rs_scene_normal(scene, (uint32_t)f), a = rs_mesh_vert(m, m->tris[3 * f]);
        if (rs_v3_len(nrm) == 0) continue;
        double top = -INFINITY;
        for (int k = 0; k < 8; k++) {
            rs_v3 corner = rs_v3_make(k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1], k & 4 ? hi[2] : lo[2]);
            top = fmax(top, rs_v3_dot(nrm, rs_v3_sub(corner, a)));
        }
        n += top <= eps;
    }
    return n;
}

/* edge_refine: pose refinement by aligning model edges with panorama edges (see edge_refine.h).
 * Model edges are 3D points fixed on the model, re-projected by each candidate pose. */
#include "calib/edge_refine.h"

#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "calib/calib_math.h"
#include "calib/cv_adapter.h"
#include "common/linsolve.h"

void rs_edge_refine_defaults(rs_edge_refine_opts *o)
{
    o->levels = 3;
    o->max_width = 2048;
    /* A lit and a shaded face of a wall differ by ln 2 or more; sensor noise and plaster texture
     * stay well below 0.05 per pixel after the 1 px blur. */
    o->edge_lo = 0.05;
    o->edge_hi = 0.15;
    o->crease_deg = 30;
    o->robust_px = 2;
    o->max_dist_px = 10;
    o->min_edges = 50;
    o->iterations = 50;
}

/* One pyramid level: linear luminance, then the image edges' distance transform. */
typedef struct {
    int w, h;
    float *lum;  /* w x h linear luminance */
    float *dist; /* w x h px to the nearest image edge, clipped at max_dist_px */
    long image_edges;
} level;

/* Columns copied across the seam on each side before edge detection, so that edges and
 * distances wrap in azimuth like the panorama does. */
#define SEAM_PAD 32

static int level_edges(level *lv, const rs_edge_refine_opts *o, rs_err *err)
{
    int pw = lv->w + 2 * SEAM_PAD, rc = -1;
    size_t n = (size_t)pw * lv->h;
    float *lnl = malloc(n * sizeof *lnl), *dist = malloc(n * sizeof *dist);
    unsigned char *edges = malloc(n);
    if (!lnl || !dist || !edges) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    /* ln of luminance, floored at a thousandth of the mean so that black pixels stay finite. */
    double mean = 0;
    for (size_t k = 0; k < (size_t)lv->w * lv->h; k++) mean += lv->lum[k];
    mean /= (double)lv->w * lv->h;
    double floor_lum = fmax(1e-3 * mean, 1e-30);
    for (int r = 0; r < lv->h; r++)
        for (int c = 0; c < pw; c++) {
            int src = ((c - SEAM_PAD) % lv->w + lv->w) % lv->w;
            lnl[(size_t)r * pw + c] = (float)log(fmax(lv->lum[(size_t)r * lv->w + src], floor_lum));
        }
    char msg[512];
    long count = 0;
    if (rs_cv_edge_distance(lnl, pw, lv->h, 1.0, o->edge_lo, o->edge_hi, edges, dist, &count, msg, sizeof msg) != 0) {
        rs_err_set(err, RS_ERR_INTERNAL, NULL, 0, "edge detection: %s", msg);
        goto out;
    }
    lv->image_edges = 0;
    for (int r = 0; r < lv->h; r++)
        for (int c = 0; c < lv->w; c++) {
            size_t k = (size_t)r * pw + c + SEAM_PAD;
            lv->image_edges += edges[k] != 0;
            lv->dist[(size_t)r * lv->w + c] = count ? (float)fmin(dist[k], o->max_dist_px) : (float)o->max_dist_px;
        }
    rc = 0;
out:
    free(lnl);
    free(dist);
    free(edges);
    return rc;
}

static void levels_free(level *lv, int n)
{
    for (int l = 0; l < n; l++) {
        free(lv[l].lum);
        free(lv[l].dist);
    }
}

/* The pyramid: level 0 is the finest (the panorama box-averaged down to <= max_width), each
 * next one half as wide. */
static int build_levels(const rs_image *pano, const rs_edge_refine_opts *o, level *lv, rs_err *err)
{
    int f = 1;
    while (pano->width / f > o->max_width && pano->width % (2 * f) == 0 && pano->height % (2 * f) == 0) f *= 2;
    for (int l = 0; l < o->levels; l++) {
        lv[l].w = pano->width / (f << l);
        lv[l].h = pano->height / (f << l);
        if (lv[l].w < 16 || lv[l].h < 8)
            return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                              "a %d x %d panorama is too small for %d pyramid levels: "
                              "level %d would be %d x %d, expected at least 16 x 8",
                              pano->width, pano->height, o->levels, l + 1, lv[l].w, lv[l].h);
        lv[l].lum = calloc((size_t)lv[l].w * lv[l].h, sizeof(float));
        lv[l].dist = calloc((size_t)lv[l].w * lv[l].h, sizeof(float));
        if (!lv[l].lum || !lv[l].dist) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    }
    /* Rec. 709 luminance; negative and non-finite radiance counts as black. */
    for (int r = 0; r < pano->height / f * f; r++)
        for (int c = 0; c < pano->width / f * f; c++) {
            const float *px = rs_image_px(pano, c, r);
            double y = pano->channels >= 3 ? 0.2126 * px[0] + 0.7152 * px[1] + 0.0722 * px[2] : px[0];
            if (!(y > 0) || !isfinite(y)) y = 0;
            lv[0].lum[(size_t)(r / f) * lv[0].w + c / f] += (float)(y / ((double)f * f));
        }
    for (int l = 1; l < o->levels; l++)
        for (int r = 0; r < lv[l].h; r++)
            for (int c = 0; c < lv[l].w; c++) {
                const float *a = lv[l - 1].lum + (size_t)(2 * r) * lv[l - 1].w + 2 * c;
                lv[l].lum[(size_t)r * lv[l].w + c] = 0.25f * (a[0] + a[1] + a[lv[l - 1].w] + a[lv[l - 1].w + 1]);
            }
    for (int l = 0; l < o->levels; l++)
        if (level_edges(&lv[l], o, err) != 0) return -1;
    return 0;
}

/* Model edges seen from pose on a w x h panorama: one ray per pixel centre, then between each
 * pixel and its right and lower neighbours a silhouette (one ray hits, the other escapes), a
 * depth step (the nearer surface's plane does not contain the farther point) or a crease (the
 * normals differ by more than crease_deg). Each edge becomes one 3D point at the boundary of the
 * two pixels, on the nearer surface: unbiased across the edge, and fixed on the model as the
 * pose changes. *pts is allocated (caller frees). */
static int model_edges(const rs_scene *scene, const rs_pose *pose, int w, int h, double crease_deg, rs_v3 **pts,
                       long *count, rs_err *err)
{
    size_t n = (size_t)w * h;
    uint32_t *face = malloc(n * sizeof *face);
    float *dist = malloc(n * sizeof *dist);
    rs_v3 *out = NULL;
    int fail = 0;
    *pts = NULL;
    *count = 0;
    if (!face || !dist) {
        free(face);
        free(dist);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    }
#pragma omp parallel
    {
        rs_ray *rays = malloc((size_t)w * sizeof *rays);
        rs_hit *hits = malloc((size_t)w * sizeof *hits);
        if (!rays || !hits) {
#pragma omp atomic write
            fail = 1;
        }
#pragma omp for schedule(dynamic, 4)
        for (int r = 0; r < h; r++) {
            if (!rays || !hits) continue;
            for (int c = 0; c < w; c++) {
                rays[c].org = pose->position;
                rays[c].dir = rs_pose_dir_to_world(pose, rs_pano_pixel_dir(w, h, c, r));
                rays[c].tnear = 0;
                rays[c].tfar = INFINITY;
            }
            rs_scene_intersect(scene, rays, hits, (size_t)w);
            for (int c = 0; c < w; c++) {
                face[(size_t)r * w + c] = hits[c].face;
                dist[(size_t)r * w + c] = hits[c].t;
            }
        }
        free(rays);
        free(hits);
    }
    if (fail) {
        free(face);
        free(dist);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    }
    size_t cap = 1024;
    out = malloc(cap * sizeof *out);
    double cos_crease = cos(crease_deg * M_PI / 180), px_rad = M_PI / h;
    for (int r = 0; r < h && out; r++)
        for (int c = 0; c < w && out; c++) {
            size_t p = (size_t)r * w + c;
            rs_v3 dp = rs_pose_dir_to_world(pose, rs_pano_pixel_dir(w, h, c, r));
            for (int k = 0; k < 2; k++) {
                int c2 = k == 0 ? (c + 1) % w : c, r2 = k == 0 ? r : r + 1;
                if (r2 >= h) continue;
                size_t q = (size_t)r2 * w + c2;
                if (face[p] == face[q]) continue;
                rs_v3 dq = rs_pose_dir_to_world(pose, rs_pano_pixel_dir(w, h, c2, r2));
                rs_v3 mid = rs_v3_norm(rs_v3_add(dp, dq));
                int edge = 0;
                double t_near;
                rs_v3 point;
                if (face[p] == RS_NO_HIT || face[q] == RS_NO_HIT) {
                    edge = 1;
                    t_near = face[p] == RS_NO_HIT ? dist[q] : dist[p];
                    point = rs_v3_add(pose->position, rs_v3_scale(mid, t_near));
                } else {
                    rs_v3 xp = rs_v3_add(pose->position, rs_v3_scale(dp, dist[p]));
                    rs_v3 xq = rs_v3_add(pose->position, rs_v3_scale(dq, dist[q]));
                    rs_v3 np = rs_scene_normal(scene, face[p]), nq = rs_scene_normal(scene, face[q]);
                    /* Normals turned toward the camera: a face seen from its back counts the same. */
                    if (rs_v3_dot(np, dp) > 0) np = rs_v3_scale(np, -1);
                    if (rs_v3_dot(nq, dq) > 0) nq = rs_v3_scale(nq, -1);
                    rs_v3 gap = rs_v3_sub(xq, xp);
                    double off_plane = fmax(fabs(rs_v3_dot(np, gap)), fabs(rs_v3_dot(nq, gap)));
                    t_near = fmin(dist[p], dist[q]);
                    if (off_plane > 3 * t_near * px_rad) {
                        edge = 1;
                        point = rs_v3_add(pose->position, rs_v3_scale(mid, t_near));
                    } else if (rs_v3_dot(np, nq) < cos_crease) {
                        edge = 1;
                        point = rs_v3_scale(rs_v3_add(xp, xq), 0.5);
                    }
                }
                if (!edge) continue;
                if ((size_t)*count == cap) {
                    rs_v3 *grown = realloc(out, 2 * cap * sizeof *out);
                    if (!grown) {
                        free(out);
                        out = NULL;
                        break;
                    }
                    out = grown;
                    cap *= 2;
                }
                out[(*count)++] = point;
            }
        }
    free(face);
    free(dist);
    if (!out) {
        *count = 0;
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    }
    *pts = out;
    return 0;
}

/* A candidate pose as a change from the level's base pose: rotation base * exp(w) (local frame),
 * centre base + dp (world, m). */
typedef struct {
    double rt[9]; /* (base rotation * exp(w))^T: world -> local */
    rs_v3 centre;
} cand;

static void cand_make(const rs_pose *base, const double x[6], cand *c, rs_pose *pose_out)
{
    double e[9], r[9];
    rs_calib_rot_exp(x, e);
    rs_calib_m3_mul(base->rot, e, r);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) c->rt[3 * i + j] = r[3 * j + i];
    c->centre = rs_v3_make(base->position.x + x[3], base->position.y + x[4], base->position.z + x[5]);
    if (pose_out) {
        memcpy(pose_out->rot, r, sizeof r);
        pose_out->position = c->centre;
    }
}

/* Continuous pixel coordinates (pixel centres at integers) of world point X seen from c. */
static void project(const cand *c, rs_v3 x, int w, int h, double *px, double *py)
{
    double u, v;
    rs_pano_dir_to_uv(rs_m3_mul_v(c->rt, rs_v3_sub(x, c->centre)), &u, &v);
    *px = u * w - 0.5;
    *py = v * h - 0.5;
}

/* Bilinear sample of the distance map, wrapping in azimuth and clamping at the poles. */
static double sample(const level *lv, double x, double y)
{
    y = fmin(fmax(y, 0), lv->h - 1);
    double fx = floor(x), fy = floor(y);
    double ax = x - fx, ay = y - fy;
    int c0 = (((int)fx % lv->w) + lv->w) % lv->w, c1 = (c0 + 1) % lv->w;
    int r0 = (int)fy, r1 = r0 + 1 < lv->h ? r0 + 1 : r0;
    const float *d = lv->dist;
    return (1 - ay) * ((1 - ax) * d[(size_t)r0 * lv->w + c0] + ax * d[(size_t)r0 * lv->w + c1]) +
        ay * ((1 - ax) * d[(size_t)r1 * lv->w + c0] + ax * d[(size_t)r1 * lv->w + c1]);
}

/* Cauchy's robust cost of a chamfer distance r (px) with scale s, and its IRLS weight. */
static double rho(double r, double s)
{
    return 0.5 * s * s * log1p((r / s) * (r / s));
}
static double weight(double r, double s)
{
    return 1.0 / (1.0 + (r / s) * (r / s));
}

static int cmp_float(const void *a, const void *b)
{
    float fa = *(const float *)a, fb = *(const float *)b;
    return (fa > fb) - (fa < fb);
}

/* Mean robust cost of the points under candidate x; the median distance into *median_px when
 * not NULL. */
static double cost(const level *lv, const rs_pose *base, const double x[6], const rs_v3 *pts, long n,
                   const rs_edge_refine_opts *o, double *median_px)
{
    cand c;
    cand_make(base, x, &c, NULL);
    double sum = 0;
    float *d = median_px ? malloc((size_t)n * sizeof *d) : NULL;
    for (long i = 0; i < n; i++) {
        double px, py;
        project(&c, pts[i], lv->w, lv->h, &px, &py);
        double r = sample(lv, px, py);
        sum += rho(r, o->robust_px);
        if (d) d[i] = (float)r;
    }
    if (median_px) {
        *median_px = NAN;
        if (d && n > 0) {
            /* Partial selection is not worth the code for a report: sort. */
            qsort(d, (size_t)n, sizeof *d, cmp_float);
            *median_px = d[n / 2];
        }
        free(d);
    }
    return n > 0 ? sum / n : 0;
}

/* Levenberg-Marquardt on the IRLS-weighted chamfer residuals of one level, from *pose (updated).
 * The Jacobian is the distance map's gradient (central differences over one pixel) times the
 * projection's derivative (forward differences: the projection is smooth, the map is not). */
static void refine_level(const level *lv, rs_pose *pose, const rs_v3 *pts, long n, const rs_edge_refine_opts *o,
                         int *iterations)
{
    static const double step[6] = {1e-6, 1e-6, 1e-6, 1e-5, 1e-5, 1e-5}; /* rad, rad, rad, m, m, m */
    double x[6] = {0}, lambda = 1e-3, a[36], g[6];
    double cur = cost(lv, pose, x, pts, n, o, NULL);
    int stale = 1;
    for (int it = 0; it < o->iterations; it++) {
        (*iterations)++;
        if (stale) {
            cand c0, cj[6];
            cand_make(pose, x, &c0, NULL);
            for (int j = 0; j < 6; j++) {
                double xj[6];
                memcpy(xj, x, sizeof xj);
                xj[j] += step[j];
                cand_make(pose, xj, &cj[j], NULL);
            }
            memset(a, 0, sizeof a);
            memset(g, 0, sizeof g);
            for (long i = 0; i < n; i++) {
                double px, py, jac[6];
                project(&c0, pts[i], lv->w, lv->h, &px, &py);
                double r = sample(lv, px, py);
                if (r >= o->max_dist_px) continue; /* clipped: flat, no pull */
                double gx = sample(lv, px + 0.5, py) - sample(lv, px - 0.5, py);
                double gy = sample(lv, px, py + 0.5) - sample(lv, px, py - 0.5);
                for (int j = 0; j < 6; j++) {
                    double qx, qy;
                    project(&cj[j], pts[i], lv->w, lv->h, &qx, &qy);
                    double dx = qx - px;
                    if (dx > lv->w / 2.0) dx -= lv->w;
                    if (dx < -lv->w / 2.0) dx += lv->w;
                    jac[j] = (gx * dx + gy * (qy - py)) / step[j];
                }
                double wi = weight(r, o->robust_px);
                for (int j = 0; j < 6; j++) {
                    g[j] += wi * jac[j] * r;
                    for (int k = 0; k < 6; k++) a[6 * j + k] += wi * jac[j] * jac[k];
                }
            }
            stale = 0;
        }
        double m[36], delta[6];
        memcpy(m, a, sizeof m);
        double trace = 0;
        for (int j = 0; j < 6; j++) trace += a[7 * j];
        if (!(trace > 0)) break; /* no point within reach of an image edge */
        for (int j = 0; j < 6; j++) {
            m[7 * j] += lambda * a[7 * j] + 1e-12 * trace;
            delta[j] = -g[j];
        }
        if (rs_solve_dense(m, delta, 6) != 0) {
            lambda *= 10;
            continue;
        }
        double xn[6];
        for (int j = 0; j < 6; j++) xn[j] = x[j] + delta[j];
        double next = cost(lv, pose, xn, pts, n, o, NULL);
        if (next < cur) {
            memcpy(x, xn, sizeof x);
            cur = next;
            stale = 1;
            lambda = fmax(lambda / 3, 1e-7);
            double turn = sqrt(delta[0] * delta[0] + delta[1] * delta[1] + delta[2] * delta[2]);
            double shift = sqrt(delta[3] * delta[3] + delta[4] * delta[4] + delta[5] * delta[5]);
            if (turn < 1e-7 && shift < 1e-6) break;
        } else {
            lambda *= 4;
            if (lambda > 1e8) break;
        }
    }
    cand c;
    cand_make(pose, x, &c, pose);
}

int rs_edge_refine(const rs_scene *scene, const rs_image *pano, const rs_pose *start, const rs_edge_refine_opts *opts,
                   rs_edge_refine_result *res, rs_err *err)
{
    enum { MAX_LEVELS = 8 };
    level lv[MAX_LEVELS];
    memset(lv, 0, sizeof lv);
    memset(res, 0, sizeof *res);
    rs_v3 *pts = NULL;
    long n = 0;
    int rc = -1;
    if (pano->width != 2 * pano->height)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                          "the panorama is %d x %d: expected width = 2 x height "
                          "(equirectangular)",
                          pano->width, pano->height);
    if (opts->levels < 1 || opts->levels > MAX_LEVELS)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "%d pyramid levels: expected 1 to %d", opts->levels, MAX_LEVELS);
    if (build_levels(pano, opts, lv, err) != 0) goto out;
    for (int l = 0; l < opts->levels; l++)
        if (lv[l].image_edges < opts->min_edges) {
            rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                       "the panorama shows %ld edge pixels at %d x %d (Canny on ln "
                       "luminance, thresholds %g and %g per pixel): expected at least %d, there is nothing to "
                       "align the model's edges with",
                       lv[l].image_edges, lv[l].w, lv[l].h, opts->edge_lo, opts->edge_hi, opts->min_edges);
            goto out;
        }
    rs_pose pose = *start;
    static const double zero[6] = {0};
    /* pass levels: the start pose's cost at the finest level; then from the coarsest level to the
     * finest, the finest twice (what is visible changes with the pose); pass -2: the final cost. */
    for (int pass = opts->levels; pass >= -2; pass--) {
        const level *l = &lv[pass >= 0 && pass < opts->levels ? pass : 0];
        free(pts);
        pts = NULL;
        if (model_edges(scene, &pose, l->w, l->h, opts->crease_deg, &pts, &n, err) != 0) goto out;
        if (n < opts->min_edges) {
            rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                       "%ld model edge pixels are visible from centre (%g, %g, %g) at "
                       "%d x %d: expected at least %d (is the pose near the model, and the model more than one "
                       "flat surface?)",
                       n, pose.position.x, pose.position.y, pose.position.z, l->w, l->h, opts->min_edges);
            goto out;
        }
        if (pass == opts->levels)
            res->cost_before = cost(&lv[0], &pose, zero, pts, n, opts, &res->median_px_before);
        else if (pass == -2)
            res->cost_after = cost(&lv[0], &pose, zero, pts, n, opts, &res->median_px_after);
        else
            refine_level(l, &pose, pts, n, opts, &res->iterations);
    }
    res->pose = pose;
    res->model_edges = n;
    res->image_edges = lv[0].image_edges;
    res->finest_width = lv[0].w;
    res->turn_deg = rs_calib_rot_angle(start->rot, pose.rot) * 180 / M_PI;
    res->shift_m = rs_v3_len(rs_v3_sub(pose.position, start->position));
    rc = 0;
out:
    free(pts);
    levels_free(lv, opts->levels < MAX_LEVELS ? opts->levels : MAX_LEVELS);
    return rc;
}

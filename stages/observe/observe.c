/* observe: which facet each panorama pixel sees, and each facet's observed radiance L_i.
 * Large facets: the footprint-weighted mean of their pure pixels (pixels whose four guard rays,
 * [observe] guard_px from the centre, all hit the facet, so no mixed pixels on borders). Small facets (fewer pure pixels
 * than [observe] min_pixels): points sampled on the facet that the camera sees, each reading
 * the pixel that holds it if that pixel lies wholly on one surface. Writes observe.ply (mesh + radiance_*, observed, observe_pixels,
 * radiance_sigma_rel: the relative standard error of the facet's L from the pixels' noise, pixel_noise_variance)
 * and facet_id.exr (channel Y: facet index, -1 where the camera sees no facet). */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include "common/capture.h"
#include "pipeline/capture_load.h"
#include "common/faceprop.h"
#include "common/fileio.h"
#include "common/log.h"
#include "common/par.h"
#include "common/sampling.h"
#include "common/scene.h"
#include "common/select.h"
#include "stages/stages.h"

typedef struct {
    uint32_t face;  /* facet hit by the pixel's centre ray, RS_NO_HIT if none */
    uint8_t pure;   /* all guard rays hit the same facet, from the front */
    uint8_t smooth; /* all sub-pixel rays hit one surface: the centre hit's plane, from
                                  the front, no silhouette or crease inside the pixel */
    float weight;   /* footprint area on the facet (m^2), 0 when not usable */
    float depth;    /* distance to the hit (m) */
} pixel_hit;

/* Casts a centre ray and four guard rays per pixel, rows [row_lo, row_hi) (this MPI rank's
 * band: common/par.h); returns how many rows it traced. Each pixel's result depends on its own
 * rays alone, so any split of the rows gives the same bytes. */
static size_t trace_pixels(const rs_scene *scene, const rs_capture *cap, double cos_max_view, double guard,
                           int row_lo, int row_hi, pixel_hit *out)
{
    int w = cap->pano->width, h = cap->pano->height;
    /* The four guard rays sit `guard` pixels from the centre along the diagonals: a camera's
     * pixel integrates a footprint wider than the pixel (lens blur, demosaicing, a renderer's
     * 1.5-pixel filter), and next to a sky 50 times brighter a 1 % leak is a 50 % error. */
    const double sub[5][2] = {{0.5, 0.5},
                              {0.5 - guard, 0.5 - guard},
                              {0.5 + guard, 0.5 - guard},
                              {0.5 - guard, 0.5 + guard},
                              {0.5 + guard, 0.5 + guard}};
    /* The ray directions' azimuth terms depend on the column only: cos and sin of phi once per
     * column and sub-pixel offset (the profile had a fifth of this stage in sincos), computed
     * as rs_pano_uv_to_dir does, so the directions are the same to the bit. */
    double *azi = malloc((size_t)w * 5 * 2 * sizeof *azi);
    if (azi)
        for (int c = 0; c < w; c++)
            for (int s = 0; s < 5; s++) {
                rs_sincos_pi(1.0 - 2.0 * ((c + sub[s][0]) / w), &azi[2 * (5 * c + s) + 1], &azi[2 * (5 * c + s)]);
            }
    rs_progress *prog = rs_progress_start("observe: tracing pixels", (size_t)(row_hi - row_lo));
    size_t traced = 0;
#pragma omp parallel reduction(+ : traced)
    {
        rs_ray *rays = malloc((size_t)w * 5 * sizeof *rays);
        rs_hit *hits = malloc((size_t)w * 5 * sizeof *hits);
#pragma omp for schedule(dynamic, 4)
        for (int r = row_lo; r < row_hi; r++) {
            if (!rays || !hits) continue;
            traced++;
            double st[5], ct[5];
            for (int s = 0; s < 5; s++) rs_sincos_pi((r + sub[s][1]) / h, &st[s], &ct[s]);
            for (int c = 0; c < w; c++)
                for (int s = 0; s < 5; s++) {
                    const double *cs = azi ? azi + 2 * (5 * c + s) : NULL; /* out of memory: the slow way */
                    rs_v3 d = cs ? rs_v3_make(st[s] * cs[0], st[s] * cs[1], ct[s])
                                 : rs_pano_uv_to_dir((c + sub[s][0]) / w, (r + sub[s][1]) / h);
                    rs_ray *ray = &rays[5 * c + s];
                    ray->org = cap->pose.position;
                    ray->dir = rs_pose_dir_to_world(&cap->pose, d);
                    ray->tnear = 0;
                    ray->tfar = INFINITY;
                }
            rs_scene_intersect_coherent(scene, rays, hits, (size_t)w * 5);
            double omega = rs_pano_pixel_solid_angle(w, h, r);
            for (int c = 0; c < w; c++) {
                const rs_hit *hc = &hits[5 * c];
                pixel_hit *p = &out[(size_t)r * w + c];
                p->face = hc->face;
                p->pure = 0;
                p->smooth = 0;
                p->weight = 0;
                p->depth = hc->t;
                if (hc->face == RS_NO_HIT || hc->backface) continue;
                int pure = 1, smooth = 1;
                rs_v3 nc = rs_scene_normal(scene, hc->face);
                rs_v3 xc = rs_v3_add(rays[5 * c].org, rs_v3_scale(rays[5 * c].dir, hc->t));
                for (int s = 1; s < 5; s++) {
                    const rs_hit *hs = &hits[5 * c + s];
                    if (hs->face != hc->face || hs->backface) pure = 0;
                    if (hs->face == RS_NO_HIT || hs->backface) {
                        smooth = 0;
                        continue;
                    }
                    rs_v3 xs = rs_v3_add(rays[5 * c + s].org, rs_v3_scale(rays[5 * c + s].dir, hs->t));
                    if (rs_v3_dot(nc, rs_scene_normal(scene, hs->face)) < 0.95 ||
                        fabs(rs_v3_dot(nc, rs_v3_sub(xs, xc))) > 0.01 * hc->t)
                        smooth = 0;
                }
                double cosv = -rs_v3_dot(rays[5 * c].dir, rs_scene_normal(scene, hc->face));
                if (cosv < cos_max_view) continue; /* grazing: footprint unbounded */
                p->pure = (uint8_t)pure;
                p->smooth = (uint8_t)smooth;
                p->weight = (float)(omega * (double)hc->t * hc->t / cosv);
            }
            rs_progress_add(prog, 1);
        }
        free(rays);
        free(hits);
    }
    rs_progress_end(prog);
    free(azi);
    return traced;
}

/* Radiance of a facet too small for pixel averaging: mean over points sampled on it that the
 * camera sees from the front, each reading the pixel that holds it when that pixel lies wholly on
 * the same surface (smooth), so that sky or another surface across a silhouette or crease never
 * leaks in. Returns the number of usable points; *visible_share the share the camera sees. */
static int cmp_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

/* Relative variance of the mean of n readings of pixels pix[0..n) (repeats allowed: a pixel read
 * c times weighs c): sum over distinct pixels of c^2 noise^2, over n^2. Sorts pix. */
static double mean_noise_var(uint32_t *pix, int n, const float *noise2)
{
    qsort(pix, (size_t)n, sizeof *pix, cmp_u32);
    double v = 0;
    for (int k = 0; k < n;) {
        int first = k;
        while (k < n && pix[k] == pix[first]) k++;
        v += (double)(k - first) * (k - first) * noise2[pix[first]];
    }
    return n ? v / ((double)n * n) : 0;
}

static int small_facet_radiance(const rs_scene *scene, const rs_capture *cap, const pixel_hit *px, uint32_t f,
                                int npoints, double cos_max_view, const float *noise2, double rgb[3],
                                double *visible_share, double *var_rel)
{
    uint32_t pix[4096]; /* [observe] facet_points is at most 4096 */
    const rs_mesh *m = rs_scene_mesh(scene);
    rs_v3 a = rs_mesh_vert(m, m->tris[3 * f]), b = rs_mesh_vert(m, m->tris[3 * f + 1]),
          c = rs_mesh_vert(m, m->tris[3 * f + 2]);
    rs_v3 n = rs_scene_normal(scene, f);
    int used = 0, seen = 0, w = cap->pano->width, h = cap->pano->height;
    rgb[0] = rgb[1] = rgb[2] = 0;
    for (int k = 0; k < npoints; k++) {
        double x, y;
        rs_sobol2_owen((uint32_t)k, rs_hash_u32(f ^ 0x0b5e7u), &x, &y);
        rs_v3 p = rs_triangle_point(a, b, c, x, y);
        rs_v3 d = rs_v3_sub(p, cap->pose.position);
        rs_ray ray = {cap->pose.position, d, 0, 1.0 + 1e-3};
        rs_hit hit;
        rs_scene_intersect(scene, &ray, &hit, 1);
        if (hit.face != f || hit.backface) continue;
        seen++;
        double cosv = -rs_v3_dot(rs_v3_norm(d), n);
        if (cosv < cos_max_view) continue;
        int col, row;
        rs_pano_world_to_pixel(&cap->pose, w, h, d, &col, &row);
        size_t k2 = (size_t)row * w + col;
        const float *v = cap->pano->data + 3 * k2;
        if (!px[k2].smooth || !rs_capture_pixel_ok(v)) continue;
        for (int ch = 0; ch < 3; ch++) rgb[ch] += v[ch];
        if (used < 4096) pix[used] = (uint32_t)k2;
        used++;
    }
    *visible_share = (double)seen / npoints;
    *var_rel = mean_noise_var(pix, used < 4096 ? used : 4096, noise2);
    if (used)
        for (int ch = 0; ch < 3; ch++) rgb[ch] /= used;
    return used;
}

/* Each pixel's relative noise variance (mean over channels), from differences to the pixels two
 * away along its row and column that lie on the same plane: for two pixels of one smooth
 * surface, E[((a - b) / ((a + b) / 2))^2] = 2 sigma_rel^2 plus the true gradient, which is small
 * over two pixels except at shadow edges (where the estimate then errs high). Two pixels apart,
 * not one, because a camera's demosaicing and a renderer's pixel filter correlate neighbours.
 * Pixels with no such pair get -1; returns the median over those with one (0 if none). */
static int pixel_noise(const rs_scene *scene, const rs_capture *cap, const pixel_hit *px, float *noise2,
                       double *median, rs_err *err)
{
    int w = cap->pano->width, h = cap->pano->height;
    size_t npx = (size_t)w * h;
    /* Pixel directions from a column and a row table, the products rs_pano_uv_to_dir forms:
     * the same bits without five sin-cos pairs per pixel. */
    double *azi = malloc((size_t)w * 2 * sizeof *azi), *pol = malloc((size_t)h * 2 * sizeof *pol);
    for (int c = 0; azi && pol && c < w; c++) rs_sincos_pi(1.0 - 2.0 * ((c + 0.5) / w), &azi[2 * c + 1], &azi[2 * c]);
    for (int r = 0; azi && pol && r < h; r++) rs_sincos_pi((r + 0.5) / h, &pol[2 * r], &pol[2 * r + 1]);
#define PIXEL_DIR(c, r)                                                                                      \
    (azi && pol ? rs_v3_make(pol[2 * (r)] * azi[2 * (c)], pol[2 * (r)] * azi[2 * (c) + 1], pol[2 * (r) + 1]) \
                : rs_pano_uv_to_dir(((c) + 0.5) / w, ((r) + 0.5) / h)) /* out of memory: the slow way */
    /* MPI: each rank its band of rows (px holds every row: the pairs reach two rows out), then
     * every rank every row, for the small facets' points. */
    size_t lo, hi;
    rs_par_range((size_t)h, &lo, &hi);
#pragma omp parallel for schedule(dynamic, 8)
    for (int r = (int)lo; r < (int)hi; r++)
        for (int c = 0; c < w; c++) {
            size_t k = (size_t)r * w + c;
            noise2[k] = -1;
            const float *a = cap->pano->data + 3 * k;
            if (px[k].face == RS_NO_HIT || !px[k].smooth || !rs_capture_pixel_ok(a)) continue;
            rs_v3 n = rs_scene_normal(scene, px[k].face);
            rs_v3 x = rs_v3_scale(rs_pose_dir_to_world(&cap->pose, PIXEL_DIR(c, r)), px[k].depth);
            const int nb[4][2] = {{0, 2}, {0, -2}, {2, 0}, {-2, 0}};
            double acc = 0;
            int pairs = 0;
            for (int q = 0; q < 4; q++) {
                int r2 = r + nb[q][0], c2 = (c + nb[q][1] + w) % w;
                if (r2 < 0 || r2 >= h) continue;
                size_t k2 = (size_t)r2 * w + c2;
                const float *b = cap->pano->data + 3 * k2;
                if (px[k2].face == RS_NO_HIT || !px[k2].smooth || !rs_capture_pixel_ok(b)) continue;
                if (rs_v3_dot(n, rs_scene_normal(scene, px[k2].face)) < 0.999) continue;
                rs_v3 x2 = rs_v3_scale(rs_pose_dir_to_world(&cap->pose, PIXEL_DIR(c2, r2)), px[k2].depth);
                if (fabs(rs_v3_dot(n, rs_v3_sub(x2, x))) > 0.01 * px[k].depth) continue;
                double d2 = 0;
                int chs = 0;
                for (int ch = 0; ch < 3; ch++) {
                    double m = 0.5 * ((double)a[ch] + b[ch]);
                    if (!(m > 0)) continue;
                    d2 += ((double)a[ch] - b[ch]) * ((double)a[ch] - b[ch]) / (m * m);
                    chs++;
                }
                if (!chs) continue;
                acc += d2 / chs / 2;
                pairs++;
            }
            if (pairs) noise2[k] = (float)(acc / pairs);
        }
#undef PIXEL_DIR
    free(azi);
    free(pol);
    if (rs_par_allgather_range(noise2, (size_t)h, (size_t)w * sizeof *noise2, err) != 0) return -1;
    *median = 0;
    float *vals = malloc((npx ? npx : 1) * sizeof *vals);
    size_t nv = 0;
    if (!vals) return 0;
    for (size_t k = 0; k < npx; k++)
        if (noise2[k] >= 0) vals[nv++] = noise2[k];
    double med = 0;
    if (nv) {
        med = rs_select_kth(vals, nv, nv / 2);
    }
    free(vals);
    *median = med;
    return 0;
}

static int write_facet_ids(const rs_config *cfg, const rs_capture *cap, const pixel_hit *px, rs_err *err)
{
    int w = cap->pano->width, h = cap->pano->height;
    rs_image *ids = rs_image_new(w, h, 1);
    if (!ids) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    for (size_t k = 0; k < (size_t)w * h; k++) ids->data[k] = px[k].face == RS_NO_HIT ? -1.0f : (float)px[k].face;
    char path[4096];
    static const char *const names[] = {"Y"};
    int rc = rs_image_write_exr(ids, rs_work_path(cfg, "facet_id.exr", path, sizeof path), names, 0,
                                "facet index seen by each pixel's centre ray; -1: none", err);
    rs_image_free(ids);
    return rc;
}

/* The [observe] keys, read once. */
typedef struct {
    double cos_max_view; /* cosine of max_view_deg: pixels seen more obliquely are not used */
    double guard_px;     /* the guard rays' offset from the pixel's centre, in pixels */
    long min_pixels;     /* pure pixels a facet needs to be observed by pixels */
    int facet_points;    /* points sampled on a facet with fewer */
    double min_visible;  /* share of those points the camera must see */
} observe_opts;

static void observe_opts_read(const rs_config *cfg, observe_opts *o)
{
    o->cos_max_view = cos(rs_config_real(cfg, "observe", "max_view_deg") * M_PI / 180);
    o->guard_px = rs_config_real(cfg, "observe", "guard_px");
    o->min_pixels = rs_config_int(cfg, "observe", "min_pixels");
    o->facet_points = (int)rs_config_int(cfg, "observe", "facet_points");
    o->min_visible = rs_config_real(cfg, "observe", "min_visible");
}

/* What observe.ply carries per facet, one array each. */
typedef struct {
    size_t nf;
    double *rgb;       /* 3 per facet: the weighted sum of its pure pixels, then its radiance */
    double *wsum;      /* footprint weight of its pure pixels */
    double *npix;      /* how many pure pixels it has */
    double *var_rel;   /* relative variance of its radiance (a weighted sum until finished) */
    uint8_t *observed; /* its radiance was measured */
} facet_radiance;

static int facet_radiance_alloc(facet_radiance *fr, size_t nf)
{
    fr->nf = nf;
    fr->rgb = calloc(3 * nf, sizeof *fr->rgb);
    fr->wsum = calloc(nf, sizeof *fr->wsum);
    fr->npix = calloc(nf, sizeof *fr->npix);
    fr->var_rel = calloc(nf, sizeof *fr->var_rel);
    fr->observed = calloc(nf, 1);
    return fr->rgb && fr->wsum && fr->npix && fr->var_rel && fr->observed ? 0 : -1;
}

static void facet_radiance_free(facet_radiance *fr)
{
    free(fr->rgb);
    free(fr->wsum);
    free(fr->npix);
    free(fr->var_rel);
    free(fr->observed);
}

/* The figures of observe.json. */
typedef struct {
    size_t pixels, model_px, excluded_px, bad_px; /* all, on the model, non-finite or negative, bad on the model */
    size_t by_pixels, by_points;                  /* facets observed either way */
    double noise_median;                          /* median relative noise variance of a pixel */
    double area_seen, area_obs;                   /* area the camera sees, and of it observed (m^2) */
} observe_counts;

/* Pixels with no same-surface pair take the image's typical noise. */
static void fill_noise_gaps(float *noise2, size_t npx, double noise_median)
{
    for (size_t k = 0; k < npx; k++)
        if (noise2[k] < 0) noise2[k] = (float)noise_median;
}

/* Sums each facet's pure pixels into fr (weighted by footprint). Serial, in pixel order: the
 * sums do not depend on the thread count. */
static void accumulate_pure_pixels(const rs_capture *cap, const pixel_hit *px, const float *noise2, facet_radiance *fr,
                                   observe_counts *n)
{
    for (size_t k = 0; k < n->pixels; k++) {
        if (px[k].face == RS_NO_HIT) continue;
        n->model_px++;
        if (!px[k].pure || px[k].weight <= 0) continue;
        const float *v = cap->pano->data + 3 * k;
        if (!rs_capture_pixel_ok(v)) {
            n->bad_px++;
            continue;
        }
        uint32_t f = px[k].face;
        for (int ch = 0; ch < 3; ch++) fr->rgb[3 * f + ch] += (double)px[k].weight * v[ch];
        fr->wsum[f] += px[k].weight;
        fr->var_rel[f] += (double)px[k].weight * px[k].weight * noise2[k]; /* / wsum^2 below */
        fr->npix[f] += 1;
    }
}

/* Each facet's radiance: the mean of its pure pixels when it has enough, else from points
 * sampled on it (small_facet_radiance); unobserved facets get 0. MPI: each rank finishes its
 * range of facets (every rank holds every pixel and every facet's sums), then every rank holds
 * every facet's result; each facet's depends on that facet alone. */
static int finish_facets(const rs_scene *scene, const rs_capture *cap, const pixel_hit *px, const float *noise2,
                         const observe_opts *o, facet_radiance *fr, observe_counts *n, rs_err *err)
{
    double *rgb = fr->rgb, *wsum = fr->wsum, *var_rel = fr->var_rel;
    size_t lo, hi;
    rs_par_range(fr->nf, &lo, &hi);
#pragma omp parallel for schedule(dynamic, 64)
    for (size_t f = lo; f < hi; f++) {
        if (fr->npix[f] >= (double)o->min_pixels) {
            for (int ch = 0; ch < 3; ch++) rgb[3 * f + ch] /= wsum[f];
            var_rel[f] /= wsum[f] * wsum[f];
            fr->observed[f] = 1;
            continue;
        }
        double share, l[3], v;
        var_rel[f] = 0;
        if (rs_v3_len(rs_scene_normal(scene, (uint32_t)f)) == 0) {
            rgb[3 * f] = rgb[3 * f + 1] = rgb[3 * f + 2] = 0;
            continue; /* degenerate facet */
        }
        int used =
            small_facet_radiance(scene, cap, px, (uint32_t)f, o->facet_points, o->cos_max_view, noise2, l, &share, &v);
        if (used > 0 && share >= o->min_visible) {
            for (int ch = 0; ch < 3; ch++) rgb[3 * f + ch] = l[ch];
            var_rel[f] = v;
            fr->observed[f] = 1;
        } else {
            rgb[3 * f] = rgb[3 * f + 1] = rgb[3 * f + 2] = 0;
        }
    }
    if (rs_par_allgather_range(rgb, fr->nf, 3 * sizeof *rgb, err) != 0 ||
        rs_par_allgather_range(var_rel, fr->nf, sizeof *var_rel, err) != 0 ||
        rs_par_allgather_range(fr->observed, fr->nf, sizeof *fr->observed, err) != 0)
        return -1;
    n->by_pixels = n->by_points = 0;
    for (size_t f = 0; f < fr->nf; f++) {
        if (fr->npix[f] >= (double)o->min_pixels)
            n->by_pixels++;
        else if (fr->observed[f])
            n->by_points++;
    }
    return 0;
}

/* Area of the facets the camera sees, and of those that ended up observed: the coverage figure. */
static int seen_area(const rs_mesh *mesh, const pixel_hit *px, const uint8_t *observed, observe_counts *n, rs_err *err)
{
    uint8_t *seen = calloc(mesh->nfaces, 1);
    if (!seen) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    for (size_t k = 0; k < n->pixels; k++)
        if (px[k].face != RS_NO_HIT) seen[px[k].face] = 1;
    for (size_t f = 0; f < mesh->nfaces; f++) {
        rs_v3 c, nrm;
        double a;
        rs_mesh_face(mesh, f, &c, &nrm, &a);
        if (seen[f]) n->area_seen += a;
        if (seen[f] && observed[f]) n->area_obs += a;
    }
    free(seen);
    return 0;
}

static int write_observe_ply(const rs_config *cfg, const rs_mesh *mesh, const facet_radiance *fr, double noise_median,
                             rs_err *err)
{
    size_t nf = fr->nf;
    int rc = -1;
    rs_ply *out = rs_ply_new();
    double *column = malloc((nf ? nf : 1) * sizeof *column); /* one scalar property at a time */
    rs_ply_element *faces = out && column ? rs_mesh_to_ply(mesh, out) : NULL;
    if (!faces || rs_faceprop_add_rgb(faces, "radiance", fr->rgb) != 0 ||
        !rs_ply_add_scalar(faces, "observe_pixels", RS_PLY_INT32, fr->npix))
        goto oom;
    for (size_t f = 0; f < nf; f++) column[f] = fr->observed[f];
    if (!rs_ply_add_scalar(faces, "observed", RS_PLY_UINT8, column)) goto oom;
    for (size_t f = 0; f < nf; f++) column[f] = fr->observed[f] ? sqrt(fr->var_rel[f]) : 0;
    if (!rs_ply_add_scalar(faces, "radiance_sigma_rel", RS_PLY_FLOAT32, column)) goto oom;
    rs_ply_add_comment(out, "rhoscan %s observe: radiance_* is the observed radiance of each facet", RHOSCAN_VERSION);
    rs_ply_add_comment(out,
                       "radiance_sigma_rel: relative standard error of radiance_* from the pixels' noise (each "
                       "pixel's from its same-surface neighbours two pixels away; median pixel noise %.4g)",
                       sqrt(noise_median));
    char path[4096];
    rc = rs_ply_write(out, rs_work_path(cfg, "observe.ply", path, sizeof path), 1, err);
    goto done;
oom:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory building observe.ply");
done:
    rs_ply_free(out);
    free(column);
    return rc;
}

static void report_observe(rs_report *rep, size_t nf, const observe_counts *n)
{
    rs_json_set_int(rep->metrics, "pixels", (long long)n->pixels);
    rs_json_set_int(rep->metrics, "model_pixels", (long long)n->model_px);
    rs_json_set_int(rep->metrics, "excluded_pixels_nonfinite_or_negative", (long long)n->excluded_px);
    rs_json_set_int(rep->metrics, "excluded_model_pixels_bad_value", (long long)n->bad_px);
    rs_json_set_int(rep->metrics, "facets", (long long)nf);
    rs_json_set_int(rep->metrics, "observed_by_pixels", (long long)n->by_pixels);
    rs_json_set_int(rep->metrics, "observed_by_points", (long long)n->by_points);
    rs_json_set_int(rep->metrics, "unobserved", (long long)(nf - n->by_pixels - n->by_points));
    rs_json_set_num(rep->metrics, "observed_share_of_seen_area", n->area_seen > 0 ? n->area_obs / n->area_seen : 0);
    rs_json_set_num(rep->metrics, "pixel_noise_rel_median", sqrt(n->noise_median));
}

int rs_observe_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    observe_opts o;
    observe_opts_read(cfg, &o);
    char path[4096];
    int rc = -1;
    rs_capture cap = {0};
    rs_scene *scene = NULL;
    pixel_hit *px = NULL;
    float *noise2 = NULL;
    facet_radiance fr = {0};
    observe_counts n = {0};
    rs_mesh *mesh = rs_mesh_read(rs_work_path(cfg, "mesh.ply", path, sizeof path), NULL, err);
    if (!mesh) return -1;
    if (rs_capture_load(cfg, "capture", &cap, err) != 0) goto out;
    if (cap.nonfinite || cap.negative)
        rs_log_warn("%s: %zu non-finite and %zu negative pixels are excluded", cap.path, cap.nonfinite, cap.negative);
    double t0 = rs_now();
    if (!(scene = rs_scene_new(mesh, err))) goto out;
    rs_report_time(rep, "bvh", rs_now() - t0);

    size_t nf = mesh->nfaces;
    n.pixels = (size_t)cap.pano->width * cap.pano->height;
    n.excluded_px = cap.nonfinite + cap.negative;
    px = malloc(n.pixels * sizeof *px);
    noise2 = malloc(n.pixels * sizeof *noise2);
    /* A rank short of memory fails them all: the exchanges below are collective. */
    if (rs_par_any(facet_radiance_alloc(&fr, nf) != 0 || !px || !noise2)) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu pixels and %zu facets", n.pixels, nf);
        goto out;
    }
    /* MPI (common/par.h): each rank traces its band of rows, then every rank holds every row:
     * the noise pairs, the facets' sums and their sampled points read any pixel. */
    t0 = rs_now();
    size_t row_lo, row_hi;
    int w = cap.pano->width, h = cap.pano->height;
    rs_par_range((size_t)h, &row_lo, &row_hi);
    rs_par_rows_done(trace_pixels(scene, &cap, o.cos_max_view, o.guard_px, (int)row_lo, (int)row_hi, px));
    if (rs_par_allgather_range(px, (size_t)h, (size_t)w * sizeof *px, err) != 0) goto out;
    rs_report_time(rep, "trace_pixels", rs_now() - t0);
    t0 = rs_now();
    if (pixel_noise(scene, &cap, px, noise2, &n.noise_median, err) != 0) goto out;
    fill_noise_gaps(noise2, n.pixels, n.noise_median);
    rs_report_time(rep, "pixel_noise", rs_now() - t0);

    /* Every rank sums every pixel, serially in pixel order: the same bits on every rank and for
     * any N, and a pass over the pixels costs little beside their rays. */
    accumulate_pure_pixels(&cap, px, noise2, &fr, &n);
    t0 = rs_now();
    if (finish_facets(scene, &cap, px, noise2, &o, &fr, &n, err) != 0) goto out;
    rs_report_time(rep, "small_facets", rs_now() - t0);
    if (!rs_par_is_root()) { /* MPI: rank 0 writes */
        rc = 0;
        goto out;
    }
    if (seen_area(mesh, px, fr.observed, &n, err) != 0) goto out;

    if (write_facet_ids(cfg, &cap, px, err) != 0 || write_observe_ply(cfg, mesh, &fr, n.noise_median, err) != 0)
        goto out;
    report_observe(rep, nf, &n);
    if (nf - n.by_pixels - n.by_points)
        rs_report_skip(rep, "unobserved facets", "%zu facets are hidden from the camera or seen too little",
                       nf - n.by_pixels - n.by_points);
    rs_log_info("observe: %zu facets, %zu observed by pixels, %zu by points; %.1f %% of the seen area observed", nf,
                n.by_pixels, n.by_points, n.area_seen > 0 ? 100 * n.area_obs / n.area_seen : 0.0);
    rc = 0;
out:
    free(px);
    free(noise2);
    facet_radiance_free(&fr);
    rs_scene_free(scene);
    rs_capture_release(&cap);
    rs_mesh_free(mesh);
    return rc;
}

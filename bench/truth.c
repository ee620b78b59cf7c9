/* truth: the benchmark's known answer (see truth.h): sky, forward solve with a dense-sampled
 * kernel from rs_gather_facet, and the camera's panorama by ray casting. */
#include "bench/truth.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "light/gather.h"
#include "common/log.h"
#include "common/pano.h"
#include "common/scene.h"
#include "sky/skyenv.h"
#include "light/transport.h"

/* The analytic sky: a blue gradient, a glow around the sun and the sun's disc (0.53 degrees). */
static const double SUN_ELEV = 35 * M_PI / 180, SUN_AZ = 80 * M_PI / 180, SUN_RADIUS = 0.00466;

static void sky_radiance(rs_v3 d, const rs_v3 sun, double out[3])
{
    static const double horizon[3] = {0.55, 0.60, 0.70}, zenith[3] = {0.15, 0.25, 0.55}, glow[3] = {0.9, 0.8, 0.6},
                        sunc[3] = {1.0, 0.95, 0.85}, below[3] = {0.12, 0.11, 0.10};
    if (d.z < 0) {
        memcpy(out, below, sizeof below);
        return;
    }
    double gamma = acos(fmin(1, fmax(-1, rs_v3_dot(d, sun))));
    double t = sqrt(d.z), g = 2.0 * exp(-gamma / 0.15);
    /* Sun: normal irradiance 8 (about six times the sky's horizontal irradiance). */
    double lsun = gamma < SUN_RADIUS ? 8.0 / (M_PI * SUN_RADIUS * SUN_RADIUS) : 0;
    for (int ch = 0; ch < 3; ch++)
        out[ch] = horizon[ch] + (zenith[ch] - horizon[ch]) * t + glow[ch] * g + sunc[ch] * lsun;
}

rs_image *rs_bench_sky(int width, const char *hdr_path, rs_err *err)
{
    int w = width, h = width / 2;
    rs_image *src = NULL, *img = rs_image_new(w, h, 3);
    if (!img) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for a %dx%d sky", w, h), NULL;
    int overcast = hdr_path && !strcmp(hdr_path, "overcast");
    if (overcast) hdr_path = NULL;
    if (hdr_path && !(src = rs_image_read(hdr_path, err))) {
        rs_image_free(img);
        return NULL;
    }
    if (src && src->channels != 3) {
        rs_err_set(err, RS_ERR_INPUT, hdr_path, 0, "has %d channels: expected RGB", src->channels);
        rs_image_free(src);
        rs_image_free(img);
        return NULL;
    }
    rs_v3 sun = {cos(SUN_ELEV) * cos(SUN_AZ), cos(SUN_ELEV) * sin(SUN_AZ), sin(SUN_ELEV)};
#pragma omp parallel for schedule(dynamic, 8)
    for (int r = 0; r < h; r++)
        for (int c = 0; c < w; c++) {
            rs_v3 dc = rs_pano_pixel_dir(w, h, c, r);
            /* Near the sun the disc covers part of a pixel: 16 x 16 samples; elsewhere 4 x 4. */
            int n = !src && !overcast && rs_v3_dot(dc, sun) > cos(0.03) ? 16 : 4;
            double acc[3] = {0, 0, 0}, wsum = 0;
            for (int j = 0; j < n; j++)
                for (int i = 0; i < n; i++) {
                    double u = (c + (i + 0.5) / n) / w, v = (r + (j + 0.5) / n) / h, val[3];
                    double sw = sin(M_PI * v); /* solid-angle weight within the pixel */
                    if (src) {
                        float f[3];
                        rs_pano_sample(src, u, v, f);
                        for (int ch = 0; ch < 3; ch++) val[ch] = isfinite(f[ch]) && f[ch] > 0 ? f[ch] : 0;
                    } else if (overcast) { /* CIE overcast: (1 + 2 cos theta) / 3 */
                        rs_v3 d = rs_pano_uv_to_dir(u, v);
                        for (int ch = 0; ch < 3; ch++) val[ch] = d.z > 0 ? 0.8 * (1 + 2 * d.z) / 3 : 0.12;
                    } else {
                        sky_radiance(rs_pano_uv_to_dir(u, v), sun, val);
                    }
                    for (int ch = 0; ch < 3; ch++) acc[ch] += sw * val[ch];
                    wsum += sw;
                }
            for (int ch = 0; ch < 3; ch++) rs_image_px(img, c, r)[ch] = (float)(acc[ch] / wsum);
        }
    rs_image_free(src);
    return img;
}

void rs_bench_truth_free(rs_bench_truth *t)
{
    if (!t) return;
    free(t->rho);
    free(t->esky);
    free(t->G);
    free(t->L);
    free(t);
}

/* The 2 x 2 rays per pixel of panorama row r (pose: identity rotation at camera). */
static void row_rays(rs_v3 camera, int w, int h, int r, rs_ray *rays)
{
    for (int c = 0; c < w; c++)
        for (int s = 0; s < 4; s++) {
            rs_ray *ray = &rays[4 * c + s];
            ray->org = camera;
            ray->dir = rs_pano_uv_to_dir((c + 0.25 + 0.5 * (s & 1)) / w, (r + 0.25 + 0.5 * (s >> 1)) / h);
            ray->tnear = 0;
            ray->tfar = INFINITY;
        }
}

/* Facets that the camera's rays (the 2 x 2 per pixel of rs_bench_render) hit first. */
static void camera_facets(const rs_scene *scene, rs_v3 camera, int w, int h, uint8_t *seen)
{
#pragma omp parallel
    {
        rs_ray *rays = malloc((size_t)w * 4 * sizeof *rays);
        rs_hit *hits = malloc((size_t)w * 4 * sizeof *hits);
#pragma omp for schedule(dynamic, 4)
        for (int r = 0; r < h; r++) {
            if (!rays || !hits) continue;
            row_rays(camera, w, h, r, rays);
            rs_scene_intersect(scene, rays, hits, (size_t)w * 4);
            for (int k = 0; k < 4 * w; k++)
                if (hits[k].face != RS_NO_HIT) seen[hits[k].face] = 1; /* same value from any thread */
        }
        free(rays);
        free(hits);
    }
}

rs_bench_truth *rs_bench_truth_new(const rs_bench_scene *sc, const rs_image *sky, int samples, int sky_samples,
                                   int sun_samples, uint32_t seed, rs_err *err)
{
    size_t nf = sc->mesh->nfaces;
    double t0 = rs_now();
    rs_bench_truth *t = calloc(1, sizeof *t);
    rs_transport K = {0};
    rs_scene *scene = NULL;
    rs_skyenv env = {0};
    int have_env = 0;
    float *ids = malloc((size_t)sky->width * sky->height * sizeof *ids);
    rs_facet_gather *fg = calloc(nf, sizeof *fg);
    uint8_t *seen = calloc(nf, 1);
    if (!t || !ids || !fg || !seen || !(t->rho = malloc(3 * nf * sizeof(double))) ||
        !(t->esky = calloc(3 * nf, sizeof(double))) || !(t->G = malloc(3 * nf * sizeof(double))) ||
        !(t->L = malloc(3 * nf * sizeof(double))) || !(K.row_start = calloc(nf + 1, sizeof *K.row_start))) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the truth of %zu facets", nf);
        goto fail;
    }
    t->nfaces = nf;
    K.nfaces = nf;
    for (size_t f = 0; f < nf; f++)
        for (int ch = 0; ch < 3; ch++) t->rho[3 * f + ch] = sc->albedo[3 * sc->part[f] + ch];
    /* The whole sky is known here: no pixel is hidden (facet id -1 everywhere). */
    for (size_t k = 0; k < (size_t)sky->width * sky->height; k++) ids[k] = -1;
    rs_capture cap = {0};
    cap.pano = (rs_image *)sky;
    cap.pose.rot[0] = cap.pose.rot[4] = cap.pose.rot[8] = 1;
    if (rs_skyenv_build(&cap, ids, 50, 2 * M_PI * (1 - cos(3 * M_PI / 180)), 1, &env, err) != 0) goto fail;
    have_env = 1;
    if (!(scene = rs_scene_new(sc->mesh, err))) goto fail;
    /* Only what the camera sees and the closure of the light paths ending there: the rest
     * cannot change a pixel (rs_gather_run), and at 10^6 facets it is most of the model. */
    camera_facets(scene, sc->camera, sky->width, sky->height, seen);
    rs_gather_ctx g = {.scene = scene,
                       .env = &env,
                       .samples = samples,
                       .sky_samples = sky_samples,
                       .sun_samples = sun_samples,
                       .seed = seed,
                       .skip_convex = 1}; /* rays only */
    rs_gather_stats st;
    if (rs_gather_run(&g, nf, seen, fg, NULL, NULL, &st, err) != 0) goto fail;
    size_t ne = 0;
    for (size_t f = 0; f < nf; f++) ne += fg[f].nentries;
    if (!(K.col = malloc((ne ? ne : 1) * sizeof *K.col)) || !(K.k = malloc((ne ? ne : 1) * sizeof *K.k))) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu kernel entries", ne);
        goto fail;
    }
    for (size_t f = 0; f < nf; f++) {
        for (uint32_t q = 0; q < fg[f].nentries; q++) {
            K.col[K.nentries] = fg[f].entries[q].col;
            K.k[K.nentries++] = fg[f].entries[q].k;
        }
        K.row_start[f + 1] = K.nentries;
        for (int ch = 0; ch < 3; ch++) t->esky[3 * f + ch] = fg[f].esky[ch];
        free(fg[f].entries);
        fg[f].entries = NULL;
    }
    t->rays = st.rays;
    t->gathered = st.gathered;
    K.k_unseen = K.k; /* the solver reads k only */
    double residual;
    if (rs_transport_solve(&K, t->rho, t->esky, t->L, t->G, 1e-9, 100000, &residual) < 0) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory in the truth's forward solve");
        goto fail;
    }
    t->seconds = rs_now() - t0;
    goto out;
fail:
    rs_bench_truth_free(t);
    t = NULL;
out:
    if (fg)
        for (size_t f = 0; f < nf; f++) free(fg[f].entries);
    free(fg);
    free(seen);
    free(ids);
    free(K.row_start);
    free(K.col);
    free(K.k);
    if (have_env) rs_skyenv_release(&env);
    rs_scene_free(scene);
    return t;
}

rs_image *rs_bench_render(const rs_bench_scene *sc, const rs_bench_truth *t, const rs_image *sky, rs_err *err)
{
    int w = sky->width, h = sky->height;
    rs_image *img = rs_image_new(w, h, 3);
    rs_scene *scene = img ? rs_scene_new(sc->mesh, err) : NULL;
    if (!img) rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the panorama");
    if (!scene) {
        rs_image_free(img);
        return NULL;
    }
#pragma omp parallel
    {
        rs_ray *rays = malloc((size_t)w * 4 * sizeof *rays);
        rs_hit *hits = malloc((size_t)w * 4 * sizeof *hits);
#pragma omp for schedule(dynamic, 4)
        for (int r = 0; r < h; r++) {
            if (!rays || !hits) continue;
            row_rays(sc->camera, w, h, r, rays);
            rs_scene_intersect(scene, rays, hits, (size_t)w * 4);
            for (int c = 0; c < w; c++) {
                double acc[3] = {0, 0, 0};
                for (int s = 0; s < 4; s++) {
                    const rs_hit *hh = &hits[4 * c + s];
                    const float *sk = rs_image_px(sky, c, r);
                    for (int ch = 0; ch < 3; ch++)
                        acc[ch] += hh->face == RS_NO_HIT ? sk[ch] : hh->backface ? 0 : t->L[3 * (size_t)hh->face + ch];
                }
                for (int ch = 0; ch < 3; ch++) rs_image_px(img, c, r)[ch] = (float)(acc[ch] / 4);
            }
        }
        free(rays);
        free(hits);
    }
    rs_scene_free(scene);
    return img;
}

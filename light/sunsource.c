/* sunsource: the sun as an explicit source of given irradiance (see sunsource.h). A clipped
 * sun's pixels hold a lower bound of its radiance; they are replaced by a measured DNI. */
#include "light/sunsource.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/sampling.h"
#include "common/select.h"
#include "sky/skyenv.h"

static int is_sky(const rs_capture *c, const float *facet_id, size_t k)
{
    return (!facet_id || facet_id[k] < 0) && rs_capture_pixel_ok(c->pano->data + 3 * k);
}

/* World direction of the solid-angle-weighted centroid of the largest blob (8-connected,
 * wrapping in azimuth, by solid angle) of sky pixels at or above level. Returns 1, 0 when there
 * is none, -1 out of memory. */
static int largest_blob_dir(const rs_capture *c, const float *facet_id, double level, rs_v3 *dir)
{
    int w = c->pano->width, h = c->pano->height;
    size_t n = (size_t)w * h;
    uint8_t *seen = calloc(n, 1);
    uint32_t *stack = malloc(n * sizeof *stack);
    double best = 0;
    if (!seen || !stack) {
        free(seen);
        free(stack);
        return -1;
    }
    for (size_t s = 0; s < n; s++) {
        if (seen[s] || !is_sky(c, facet_id, s) || rs_skyenv_luminance(c->pano->data + 3 * s) < level) continue;
        size_t top = 0;
        double om_sum = 0;
        rs_v3 sum = {0, 0, 0};
        stack[top++] = (uint32_t)s;
        seen[s] = 1;
        while (top) {
            uint32_t k = stack[--top];
            int x = (int)(k % (uint32_t)w), y = (int)(k / (uint32_t)w);
            double om = rs_pano_pixel_solid_angle(w, h, y);
            om_sum += om;
            sum = rs_v3_add(sum, rs_v3_scale(rs_pano_pixel_dir(w, h, x, y), om));
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int yy = y + dy, xx = (x + dx + w) % w;
                    if (yy < 0 || yy >= h) continue;
                    size_t q = (size_t)yy * w + xx;
                    if (seen[q] || !is_sky(c, facet_id, q) || rs_skyenv_luminance(c->pano->data + 3 * q) < level)
                        continue;
                    seen[q] = 1;
                    stack[top++] = (uint32_t)q;
                }
        }
        if (om_sum > best && rs_v3_len(sum) > 0) {
            best = om_sum;
            *dir = rs_v3_norm(rs_pose_dir_to_world(&c->pose, sum));
        }
    }
    free(seen);
    free(stack);
    return best > 0;
}

int rs_sunsource_setup(const rs_sunsource_opts *o, rs_capture *cap, const float *facet_id, rs_skyfill_opts *fill,
                       rs_sunsource *sun, rs_err *err)
{
    memset(sun, 0, sizeof *sun);
    if (!o->dni_given && o->from_shadows != RS_SUN_SHADOWS_ON) return 0;
    sun->active = 1;
    sun->from_shadows = !o->dni_given; /* the given DNI wins */
    sun->dni = sun->from_shadows ? 0 : o->dni;
    for (int ch = 0; ch < 3; ch++) sun->rgb[ch] = o->rgb[ch];
    sun->halo_factor = o->halo_factor;
    sun->cone_rad = o->cone_rad;
    size_t npx = (size_t)cap->pano->width * cap->pano->height;
    double brightest = 0;
    if (fill->sun_given) {
        sun->dir_world = rs_v3_norm(fill->sun_dir);
        sun->dir_from = o->given_dir_from;
    }
    /* The default clip level: clipped pixels all sit near the brightest value (the shortest
     * exposure's saturation), blending across seams pulls some of them down a little. Near a
     * given sun only: a specular glint elsewhere must not set it. */
    for (size_t k = 0; k < npx; k++) {
        if (!is_sky(cap, facet_id, k)) continue;
        int col = (int)(k % (size_t)cap->pano->width), row = (int)(k / (size_t)cap->pano->width);
        rs_v3 d = rs_pose_dir_to_world(&cap->pose, rs_pano_pixel_dir(cap->pano->width, cap->pano->height, col, row));
        if (fill->sun_given && rs_v3_dot(d, sun->dir_world) < cos(sun->cone_rad)) continue;
        brightest = fmax(brightest, rs_skyenv_luminance(cap->pano->data + 3 * k));
    }
    sun->clip_level = o->clip_level_given ? o->clip_level : 0.9 * brightest;
    if (!fill->sun_given) {
        int found = sun->clip_level > 0 ? largest_blob_dir(cap, facet_id, sun->clip_level, &sun->dir_world) : 0;
        if (found < 0)
            return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory looking for the sun's disc in %s", cap->path);
        if (!found) return 1;
        sun->dir_from = "clipped disc";
        fill->sun_given = 1;
        fill->sun_dir = sun->dir_world;
    }
    rs_sunsource_remove(sun, cap, facet_id, 1);
    return 0;
}

size_t rs_sunsource_remove(rs_sunsource *sun, rs_capture *c, const float *facet_id, int count_power)
{
    if (!sun->active) return 0;
    int w = c->pano->width, h = c->pano->height;
    size_t npx = (size_t)w * h, nsky = 0, removed = 0;
    double *lum = malloc((npx ? npx : 1) * sizeof *lum);
    if (!lum) return 0;
    for (size_t k = 0; k < npx; k++)
        if (is_sky(c, facet_id, k)) lum[nsky++] = rs_skyenv_luminance(c->pano->data + 3 * k);
    double median = nsky ? rs_select_kth_double(lum, nsky, nsky / 2) : 0;
    free(lum);
    double level = sun->halo_factor * median;
    if (sun->clip_level > 0 && sun->clip_level < level) level = sun->clip_level;
    if (!(level > 0)) return 0; /* a black sky: nothing tells the sun from it */
    double cos_cone = cos(sun->cone_rad);
    for (size_t k = 0; k < npx; k++) {
        if (!is_sky(c, facet_id, k)) continue;
        int row = (int)(k / (size_t)w);
        rs_v3 d = rs_pose_dir_to_world(&c->pose, rs_pano_pixel_dir(w, h, (int)(k % (size_t)w), row));
        float *px = c->pano->data + 3 * k;
        double y = rs_skyenv_luminance(px);
        if (rs_v3_dot(d, sun->dir_world) < cos_cone || y < level) continue;
        if (count_power) {
            double om = rs_pano_pixel_solid_angle(w, h, row);
            sun->removed_sr += om;
            sun->removed_power += y * om;
            for (int ch = 0; ch < 3; ch++) sun->removed_rgb[ch] += px[ch] * om;
        }
        px[0] = px[1] = px[2] = -1; /* not ok: the sky map fills it as unseen sky */
        removed++;
    }
    sun->removed_px += removed;
    return removed;
}

int rs_sunsource_auto(const rs_sunsource_opts *o, const rs_skyenv *env, const rs_skyfill_opts *fill, rs_sunsource *sun)
{
    if (sun->active || o->from_shadows != RS_SUN_SHADOWS_AUTO) return 0;
    if (!fill->sun_given) {
        sun->search = env->bright_pixels == 0; /* no sun in the sky: perhaps behind the building */
        return 0;
    }
    rs_v3 s = rs_v3_norm(fill->sun_dir);
    if (!(s.z > 0)) return 0; /* below the horizon: no direct light */
    int w = env->width, h = env->height, c, r;
    rs_pano_world_to_pixel(&env->pose, w, h, s, &c, &r);
    if (!env->filled[(size_t)r * w + c]) return 0; /* a camera saw the sky there: the map has the sun */
    /* Bright measured pixels next to it: seen, at least in part. Not env->sun, which is empty
     * when nothing samples the sun explicitly. */
    double cone = cos(o->cone_rad);
    double bright = o->halo_factor * env->sky_median;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t k = (size_t)y * w + x;
            if (!env->filled[k] && rs_skyenv_luminance(env->radiance + 3 * k) > bright &&
                rs_v3_dot(rs_pose_dir_to_world(&env->pose, rs_pano_pixel_dir(w, h, x, y)), s) >= cone)
                return 0;
        }
    sun->active = sun->from_shadows = 1;
    sun->dir_world = s;
    sun->dir_from = o->given_dir_from;
    for (int ch = 0; ch < 3; ch++) sun->rgb[ch] = 1;
    return 1;
}

int rs_sunsource_visibility(const rs_sunsource *sun, const rs_scene *scene, int rays, uint32_t seed, size_t nf,
                            const rs_facet_gather *fg, float *vis, rs_err *err)
{
    for (size_t f = 0; f < nf; f++) vis[f] = -1;
    if (!sun->active) return 0;
    if (rays < 1) rays = 1;
    const rs_mesh *m = rs_scene_mesh(scene);
    rs_v3 s = sun->dir_world, t1, t2;
    t1 = rs_v3_norm(fabs(s.z) < 0.9 ? rs_v3_cross(s, rs_v3_make(0, 0, 1)) : rs_v3_cross(s, rs_v3_make(1, 0, 0)));
    t2 = rs_v3_cross(s, t1);
    int failed = 0;
#pragma omp parallel
    {
        rs_ray *ray = malloc((size_t)rays * sizeof *ray);
        uint8_t *occl = malloc((size_t)rays);
        if (!ray || !occl) {
#pragma omp atomic write
            failed = 1;
        }
#pragma omp for schedule(dynamic, 64)
        for (size_t f = 0; f < nf; f++) {
            if (!ray || !occl || (!fg[f].rays && !fg[f].sky_sh)) continue; /* not gathered */
            rs_v3 n = rs_scene_normal(scene, (uint32_t)f);
            if (!(rs_v3_dot(n, s) > 0)) continue;
            rs_v3 a = rs_mesh_vert(m, m->tris[3 * f]), b = rs_mesh_vert(m, m->tris[3 * f + 1]),
                  c = rs_mesh_vert(m, m->tris[3 * f + 2]);
            uint32_t fs = rs_hash_combine(rs_hash_combine(seed, (uint32_t)f), 0x5a11);
            for (int i = 0; i < rays; i++) {
                double px, py, u, v;
                rs_sobol2_owen((uint32_t)i, rs_hash_combine(fs, 1), &px, &py);
                rs_sobol2_owen((uint32_t)i, rs_hash_combine(fs, 2), &u, &v);
                /* Uniform over the disc's cone (small angle: uniform over a flat disc). */
                double r = RS_SUN_RADIUS_RAD * sqrt(u), phi = 2 * M_PI * v;
                rs_v3 d =
                    rs_v3_add(rs_v3_scale(s, cos(r)),
                              rs_v3_scale(rs_v3_add(rs_v3_scale(t1, cos(phi)), rs_v3_scale(t2, sin(phi))), sin(r)));
                rs_v3 p = rs_triangle_point(a, b, c, px, py);
                ray[i].org = rs_v3_add(p, rs_v3_scale(n, rs_scene_offset(scene, p)));
                ray[i].dir = d;
                ray[i].tnear = 0;
                ray[i].tfar = INFINITY;
            }
            rs_scene_occluded(scene, ray, occl, (size_t)rays);
            int open = 0;
            for (int i = 0; i < rays; i++) open += !occl[i];
            vis[f] = (float)open / (float)rays;
        }
        free(ray);
        free(occl);
    }
    return failed ? rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory tracing the shadow rays toward the sun") : 0;
}

/* E_sky + G of every facet, 3 each (NULL: out of memory). */
static double *irradiance_without_sun(const rs_facet_gather *fg, size_t nf, const double *radiance,
                                      const uint8_t *observed)
{
    double *E = malloc((3 * nf + 1) * sizeof *E);
    for (size_t f = 0; E && f < nf; f++) {
        rs_gather_inter_observed(&fg[f], radiance, observed, E + 3 * f);
        for (int ch = 0; ch < 3; ch++) E[3 * f + ch] += fg[f].esky[ch];
    }
    return E;
}

int rs_sunsource_search(rs_sunsource *sun, const rs_scene *scene, const rs_skyenv *env, const rs_facet_gather *fg,
                        const double *radiance, const uint8_t *observed, rs_v3 cam, int pano_height, rs_v3 sky_dir,
                        double lead_sigmas, rs_err *err)
{
    const rs_mesh *mesh = rs_scene_mesh(scene);
    double *E = irradiance_without_sun(fg, mesh->nfaces, radiance, observed);
    if (!E) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory searching the shadows for the sun");
    double margin = rs_sunshadow_margin(mesh, observed, cam, pano_height);
    rs_sunshadow_pairs pairs;
    int rc = rs_sunshadow_pairs_build(mesh, observed, margin, 3 * margin, 8, &pairs, err);
    rs_v3 prior = rs_v3_norm(sky_dir);
    int has_prior = rs_v3_len(sky_dir) > 0 && isfinite(prior.x);
    if (rc == 0)
        rc = rs_sunsearch_run(scene, env, &pairs, E, radiance, observed, has_prior ? &prior : NULL,
                              RS_SUNSOURCE_AGREE_DEG, &sun->found, err);
    rs_sunshadow_pairs_free(&pairs);
    free(E);
    if (rc < 0) return -1;
    sun->found_off_deg = acos(fmax(-1, fmin(1, rs_v3_dot(rs_v3_norm(sky_dir), sun->found.dir)))) * 180 / M_PI;
    const rs_sunsearch *f = &sun->found;
    int take = rs_sunsearch_accept(f, sun->found_off_deg, RS_SUNSOURCE_AGREE_DEG, lead_sigmas, &sun->missing_light,
                                   &sun->decisive);
    if (rc == 0 && take) {
        sun->active = sun->from_shadows = sun->searched = 1;
        sun->dir_world = sun->found.dir;
        sun->dir_from = "shadows";
        for (int ch = 0; ch < 3; ch++) sun->rgb[ch] = 1;
    }
    return 0;
}

int rs_sunsource_from_shadows(rs_sunsource *sun, const rs_mesh *mesh, const float *vis, const rs_facet_gather *fg,
                              const double *radiance, const uint8_t *observed, rs_v3 cam, int pano_height, rs_err *err)
{
    size_t nf = mesh->nfaces;
    double *E = irradiance_without_sun(fg, nf, radiance, observed);
    double *E_sigma = malloc((nf ? nf : 1) * sizeof *E_sigma);
    if (!E || !E_sigma) {
        free(E);
        free(E_sigma);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory estimating the sun from the shadows");
    }
    for (size_t f = 0; f < nf; f++) E_sigma[f] = fg[f].fill_sigma_lum;
    sun->margin = rs_sunshadow_margin(mesh, observed, cam, pano_height);
    rs_sunshadow_input in = {.mesh = mesh,
                             .vis = vis,
                             .sun_dir = sun->dir_world,
                             .E = E,
                             .L = radiance,
                             .observed = observed,
                             .E_sigma = E_sigma,
                             .margin = sun->margin,
                             .radius = 3 * sun->margin};
    sun->shadow_rc = rs_sunshadow_estimate(&in, &sun->shadow, err);
    free(E);
    free(E_sigma);
    if (sun->shadow_rc < 0) return -1;
    if (sun->shadow_rc == 0 && sun->searched && !(sun->shadow.dni_lum > 5 * sun->shadow.sigma_stat_lum))
        sun->shadow_rc = 2; /* the best of many directions: demand more */
    sun->dni = sun->shadow_rc == 0 ? sun->shadow.dni_lum : 0;
    for (int ch = 0; ch < 3; ch++) sun->rgb[ch] = sun->dni > 0 ? sun->shadow.dni[ch] / sun->dni : 1;
    if (sun->shadow_rc != 0 && sun->removed_power > 0) { /* no shadows to read: keep what was seen */
        sun->fell_back = 1;
        sun->dni = sun->removed_power;
        for (int ch = 0; ch < 3; ch++) sun->rgb[ch] = sun->removed_rgb[ch] / sun->removed_power;
    }
    return 0;
}

void rs_sunsource_apply(const rs_sunsource *sun, const rs_scene *scene, size_t nf, const float *vis,
                        rs_facet_gather *fg)
{
    if (!sun->active || !(sun->dni > 0)) return;
    for (size_t f = 0; f < nf; f++) {
        if (!(vis[f] >= 0)) continue;
        double u = fmax(0, rs_v3_dot(rs_scene_normal(scene, (uint32_t)f), sun->dir_world)) * vis[f];
        double e = sun->dni * u;
        for (int ch = 0; ch < 3; ch++) {
            fg[f].esky[ch] += e * sun->rgb[ch];
            fg[f].esun[ch] += e * sun->rgb[ch];
        }
        fg[f].esky_lum += e;                        /* rgb has luminance 1 */
        if (sun->from_shadows && !sun->fell_back) { /* inferred, not measured: filled light */
            fg[f].filled_lum += e;
            fg[f].fill_sigma_lum = hypot(fg[f].fill_sigma_lum, sun->shadow.sigma_lum * u);
        }
    }
}

/* fixtures: synthetic skies, scenes and work folders for the tests (see fixtures.h). */
#include "tests/fixtures.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/json.h"
#include "common/ply.h"
#include "common/sampling.h"
#include "tests/testutil.h"

rs_image *rs_fx_pano(int w, int h, rs_fx_radiance radiance, void *ctx)
{
    rs_image *img = rs_image_new(w, h, 3);
    assert_non_null(img);
    for (int r = 0; radiance && r < h; r++)
        for (int c = 0; c < w; c++) {
            double rgb[3];
            radiance(rs_pano_pixel_dir(w, h, c, r), (size_t)r * w + c, rgb, ctx);
            float *px = rs_image_px(img, c, r);
            for (int ch = 0; ch < 3; ch++) px[ch] = (float)rgb[ch];
        }
    return img;
}

rs_capture rs_fx_capture(int w, int h, rs_fx_radiance radiance, void *ctx)
{
    rs_capture cap;
    memset(&cap, 0, sizeof cap);
    cap.pano = rs_fx_pano(w, h, radiance, ctx);
    rs_m3_identity(cap.pose.rot);
    return cap;
}

rs_capture rs_fx_sun_pixel_capture(int w, int h, float sky, float sun, int sc, int sr)
{
    rs_capture cap = rs_fx_capture(w, h, NULL, NULL);
    for (size_t k = 0; k < 3 * (size_t)w * h; k++) cap.pano->data[k] = sky;
    float *px = rs_image_px(cap.pano, sc, sr);
    px[0] = px[1] = px[2] = sun;
    return cap;
}

void rs_fx_sky_env(const rs_capture *cap, double max_sr, int explicit_sun, rs_skyenv *env)
{
    size_t n = (size_t)cap->pano->width * cap->pano->height;
    float *ids = malloc(n * sizeof *ids);
    for (size_t k = 0; k < n; k++) ids[k] = -1;
    rs_err err;
    if (rs_skyenv_build(cap, ids, 50, max_sr, explicit_sun, env, &err) != 0) fail_msg("sky map: %s", err.msg);
    free(ids);
}

rs_skyenv_opts rs_fx_sky_opts(rs_skyfill_method method)
{
    rs_skyenv_opts o;
    memset(&o, 0, sizeof o);
    o.sun_threshold = 50;
    o.max_sr = RS_FX_SUN_MAX_SR;
    o.explicit_sun = 1;
    o.fill.method = method;
    return o;
}

void rs_fx_sky_env_opts(const rs_capture *cap, const float *facet_id, const rs_skyenv_opts *o, rs_skyenv *env,
                        rs_skyenv_info *info)
{
    rs_err err;
    if (rs_skyenv_build_opts(cap, facet_id, o, env, info, &err) != 0) fail_msg("sky map: %s", err.msg);
}

void rs_fx_random_sky(int w, float sun, int dark_every, rs_capture *cap, rs_skyenv *env)
{
    int h = w / 2;
    *cap = rs_fx_capture(w, h, NULL, NULL);
    for (size_t k = 0; k < (size_t)w * h; k++) {
        float v = 0.05f + (rs_hash_u32((uint32_t)k) >> 8) / 16777216.0f;
        if (dark_every > 0 && k % (size_t)dark_every == 0) v = 0; /* pixels without power inside the map */
        for (int ch = 0; ch < 3; ch++) cap->pano->data[3 * k + ch] = v;
    }
    for (int c = 0; c < 6; c++)
        for (int r = 0; r < 3; r++) {
            float *px = rs_image_px(cap->pano, w / 2 + 20 + c, h / 4 + r);
            px[0] = px[1] = px[2] = sun;
        }
    rs_fx_sky_env(cap, 0.01, 1, env);
}

rs_scene *rs_fx_scene(const rs_mesh *m)
{
    rs_err err;
    rs_scene *scene = rs_scene_new(m, &err);
    if (!scene) fail_msg("scene: %s", err.msg);
    return scene;
}

rs_mesh *rs_fx_unit_square(void)
{
    rs_meshgen g = rs_meshgen_new(16, 8);
    rs_meshgen_rect(&g, rs_v3_make(0, 0, 0), rs_v3_make(1, 0, 0), rs_v3_make(0, 1, 0), 1, 1);
    return rs_meshgen_done(&g);
}

rs_gather_ctx rs_fx_gather_ctx(const rs_scene *scene, const rs_skyenv *env, int samples, int sun_samples, uint32_t seed)
{
    rs_gather_ctx g = {.scene = scene,
                       .env = env,
                       .samples = samples,
                       .sky_samples = samples,
                       .sun_samples = sun_samples,
                       .seed = seed,
                       .skip_convex = 1};
    return g;
}

void rs_fx_release(rs_skyenv *env, rs_capture *cap, rs_scene *scene, rs_mesh *m)
{
    if (env) rs_skyenv_release(env);
    if (cap) rs_capture_release(cap);
    rs_scene_free(scene);
    rs_mesh_free(m);
}

void rs_fx_write_pano(const rs_image *img, const char *dir)
{
    static const char *const rgb[] = {"R", "G", "B"};
    rs_err err;
    if (rs_image_write_exr(img, rs_test_path(dir, "pano.exr"), rgb, 0, NULL, &err) != 0) fail_msg("%s", err.msg);
}

void rs_fx_write_floor_wall(const char *dir, int floor_cells, int wall_nu, int wall_nv)
{
    size_t fc = (size_t)floor_cells, nu = (size_t)wall_nu, nv = (size_t)wall_nv;
    rs_meshgen g = rs_meshgen_new((fc + 1) * (fc + 1) + (nu + 1) * (nv + 1), 2 * (fc * fc + nu * nv));
    rs_meshgen_rect(&g, rs_v3_make(-5, -5, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 10, 0), floor_cells, floor_cells);
    size_t wall =
        rs_meshgen_rect(&g, rs_v3_make(-5, 5, 0), rs_v3_make(10, 0, 0), rs_v3_make(0, 0, 6), wall_nu, wall_nv);
    rs_mesh *m = rs_meshgen_done(&g);
    for (size_t f = wall; f < m->nfaces; f++) { /* e1 x e2 points +y: swap the winding */
        uint32_t t = m->tris[3 * f + 1];
        m->tris[3 * f + 1] = m->tris[3 * f + 2];
        m->tris[3 * f + 2] = t;
    }
    rs_meshgen_write(m, rs_test_path(dir, "mesh.ply"));
    rs_mesh_free(m);
}

const char *rs_fx_write_scene_ini(const char *dir, const char *position, int samples, int sun_samples,
                                  const char *extra)
{
    char text[8192];
    snprintf(text, sizeof text,
             "[pipeline]\nworkdir = work\n[mesh]\ninput_mesh = mesh.ply\n[capture]\npanorama = pano.exr\n"
             "position = %s\n[irradiance]\nsamples = %d\nsky_samples = %d\nsun_samples = %d\n%s",
             position, samples, samples, sun_samples, extra ? extra : "");
    const char *path = rs_test_path(dir, "scene.ini");
    rs_test_write(path, text);
    return path;
}

void rs_fx_write_wall_ground_pano(const char *dir, int w, const rs_fx_wall_ground_view *view, const rs_image *facet_id,
                                  const double *ground)
{
    int h = w / 2;
    rs_image *img = rs_image_new(w, h, 3);
    for (int r = 0; r < h; r++)
        for (int c = 0; c < w; c++) {
            rs_v3 d = rs_pano_pixel_dir(w, h, c, r);
            int what = rs_meshgen_wall_ground_sees(&view->scene, view->camera, d);
            float *px = rs_image_px(img, c, r);
            for (int ch = 0; ch < 3; ch++) {
                double v = d.z > 0 ? view->sky(d, view->sky_ctx) : view->far_ground;
                if (what == 2) v = view->wall;
                if (what == 1) {
                    float id = facet_id ? facet_id->data[(size_t)r * w + c] : -1;
                    v = ground && id >= 0 ? ground[3 * (size_t)id + ch] : 0.2;
                }
                px[ch] = (float)v;
            }
        }
    rs_fx_write_pano(img, dir);
    rs_image_free(img);
}

void rs_fx_report_init(rs_report *rep)
{
    rep->metrics = rs_json_object();
    rep->skipped = rs_json_array();
    rep->timings = rs_json_object();
    rep->skips = NULL;
    rep->stage = "test";
}

void rs_fx_report_free(rs_report *rep)
{
    rs_json_free(rep->metrics);
    rs_json_free(rep->skipped);
    rs_json_free(rep->timings);
}

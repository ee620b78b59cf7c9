/* Sky completion on a synthetic sky: an analytic Perez sky with a low sun, partly hidden by a
 * courtyard-like occluder, filled by rows and by the fitted model; the sky-panorama path; a second
 * capture; the solar position algorithm against NREL's published SPA example. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "sky/skydist.h"
#include "sky/skyenv.h"
#include "sky/solar.h"
#include "tests/fixtures.h"
#include "tests/testutil.h"

/* The panorama's size: 512 x 256 but for test_cv_on_coarser_map. */
static int W = 512, H = 256;

static const double truth_perez[3][5] = {
    {-1, -0.30, 12, -3.2, 0.45}, {-1, -0.32, 10, -3.0, 0.45}, {-1, -0.36, 8, -2.8, 0.5}};
static const double truth_zenith[3] = {0.9, 1.0, 1.3};

static rs_v3 sun_dir(double az_deg, double el_deg)
{
    double a = az_deg * M_PI / 180, e = el_deg * M_PI / 180;
    return rs_v3_make(cos(e) * cos(a), cos(e) * sin(a), sin(e));
}

/* Truth radiance toward d: Perez per channel times a smooth 10 % gradient the model's harmonics
 * must pick up; below the horizon a ground of radiance 0.4. */
static void truth_sky(rs_v3 d, rs_v3 sun, double rgb[3])
{
    for (int ch = 0; ch < 3; ch++) {
        if (d.z <= 0) {
            rgb[ch] = 0.4;
            continue;
        }
        double g = atan2(rs_v3_len(rs_v3_cross(d, sun)), rs_v3_dot(d, sun));
        rgb[ch] = truth_zenith[ch] * rs_skymodel_perez(truth_perez[ch], d.z, g) * exp(0.1 * d.x);
    }
}

static void truth_radiance(rs_v3 d, size_t k, double rgb[3], void *sun)
{
    (void)k;
    truth_sky(d, *(const rs_v3 *)sun, rgb);
}

/* A panorama (identity pose) of the truth sky with a sun of one pixel at 1e5 x. */
static rs_capture make_capture(rs_v3 sun)
{
    rs_capture cap = rs_fx_capture(W, H, truth_radiance, &sun);
    int c, r;
    rs_pano_world_to_pixel(&cap.pose, W, H, sun, &c, &r);
    for (int ch = 0; ch < 3; ch++) rs_image_px(cap.pano, c, r)[ch] = 1e5f;
    return cap;
}

/* Courtyard occluder: walls hide everything up to 40 degrees elevation except a low gap (5
 * degrees) 70 degrees wide in azimuth whose edge passes 20 degrees from the sun; the ground
 * below the horizon is the model's own floor. facet_id >= 0 marks what the model hides. */
static float *courtyard_ids(double sun_az_deg)
{
    float *ids = malloc((size_t)W * H * sizeof *ids);
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++) {
            rs_v3 d = rs_pano_pixel_dir(W, H, c, r);
            double el = asin(d.z) * 180 / M_PI, az = atan2(d.y, d.x) * 180 / M_PI;
            double rel = fmod(az - sun_az_deg + 540, 360) - 180;
            double wall = (rel > -50 && rel < 20) ? 5 : 40;
            ids[(size_t)r * W + c] = el < wall ? 0.0f : -1.0f;
        }
    return ids;
}

/* Irradiance of a facet with normal n from the map's directions flagged in `which` (NULL: all),
 * and the same from the truth (sun pixel as it is in the map). */
static void irradiance_pair(const rs_skyenv *env, const rs_capture *cap, const uint8_t *which, rs_v3 n, double *e_map,
                            double *e_truth)
{
    *e_map = *e_truth = 0;
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++) {
            size_t k = (size_t)r * W + c;
            rs_v3 d = rs_pano_pixel_dir(W, H, c, r);
            double cs = rs_v3_dot(d, n), om = rs_pano_pixel_solid_angle(W, H, r);
            if (cs <= 0 || (which && !which[k]) || d.z <= 0) continue;
            *e_map += om * cs * rs_skyenv_luminance(env->radiance + 3 * k);
            *e_truth += om * cs * rs_skyenv_luminance(cap->pano->data + 3 * k);
        }
}

static rs_skyenv_opts opts(rs_skyfill_method method)
{
    rs_skyenv_opts o = rs_fx_sky_opts(method);
    o.fill.sun_mask_rad = 4 * M_PI / 180;
    o.fill.sh_order = 2;
    o.fill.sh_ridge = 1e-3;
    o.fill.ground_albedo = 0.2;
    o.fill.cross_validate = 1;
    return o;
}

/* The model fill recovers the light from hidden directions on walls facing every way within 4 %,
 * and at least 3 times better than rows near the low sun. */
static void test_low_sun_courtyard(void **state)
{
    (void)state;
    const double sun_az = 30, sun_el = 8;
    rs_capture cap = make_capture(sun_dir(sun_az, sun_el));
    float *ids = courtyard_ids(sun_az);
    double worst_model = 0, worst_row = 0, sum_model = 0, sum_row = 0;
    rs_skyenv env[2];
    rs_skyenv_info info[2];
    for (int m = 0; m < 2; m++) {
        rs_skyenv_opts o = opts(m ? RS_SKYFILL_MODEL : RS_SKYFILL_ROW);
        rs_fx_sky_env_opts(&cap, ids, &o, &env[m], &info[m]);
    }
    rs_v3 s = info[1].fill.sun_dir;
    print_message("sun found %.2f deg from the truth; held-out error rows %.3f, model %.3f (%d blocks); "
                  "residual order %d, fit rms %.4f\n",
                  acos(fmin(1, rs_v3_dot(s, sun_dir(sun_az, sun_el)))) * 180 / M_PI, info[1].fill.cv_rel_row,
                  info[1].fill.cv_rel_model, info[1].fill.cv_folds, info[1].fill.model.sh_order,
                  info[1].fill.model.fit_rms_log);
    assert_true(rs_v3_dot(s, sun_dir(sun_az, sun_el)) > cos(1.0 * M_PI / 180));
    for (int a = 0; a < 12; a++) {
        double az = sun_az + 30 * a;
        rs_v3 n = rs_v3_make(cos(az * M_PI / 180), sin(az * M_PI / 180), 0);
        double em, et, er, et2;
        irradiance_pair(&env[1], &cap, env[1].filled, n, &em, &et);
        irradiance_pair(&env[0], &cap, env[0].filled, n, &er, &et2);
        double rm = fabs(em - et) / et, rr = fabs(er - et) / et;
        print_message("wall facing %5.0f deg: hidden-sky E truth %.4f, model %.4f (%.2f %%), rows %.4f (%.2f %%)\n", az,
                      et, em, 100 * rm, er, 100 * rr);
        worst_model = fmax(worst_model, rm);
        worst_row = fmax(worst_row, rr);
        sum_model += rm;
        sum_row += rr;
    }
    print_message("worst: model %.2f %%, rows %.2f %%; mean: model %.2f %%, rows %.2f %%\n", 100 * worst_model,
                  100 * worst_row, 100 * sum_model / 12, 100 * sum_row / 12);
    assert_true(worst_model < 0.04);
    assert_true(sum_row > 3 * sum_model);
    /* The held-out error the uncertainty is built on says the same. */
    assert_true(info[1].fill.cv_rel_model < info[1].fill.cv_rel_row);
    assert_true(env[1].fill_sigma > 0 && env[1].fill_sigma == info[1].fill.cv_rel_model);
    for (int m = 0; m < 2; m++) rs_skyenv_release(&env[m]);
    free(ids);
    rs_capture_release(&cap);
}

/* Below the horizon a filled pixel copies measured ground only within RS_SKYFILL_GROUND_NEAR_RAD
 * of a band that has some: a camera that sees ground beyond the model only 0 to 4 degrees down
 * leaves the steeper directions to the ground model (ground_albedo E_horizontal / pi per
 * channel, marked), which rs_skyenv_set_ground sets again with the distributions rebuilt. */
static void test_ground_near_bands_and_model(void **state)
{
    (void)state;
    rs_capture cap = make_capture(sun_dir(30, 40));
    float *ids = malloc((size_t)W * H * sizeof *ids);
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++) {
            double el = asin(rs_pano_pixel_dir(W, H, c, r).z) * 180 / M_PI;
            ids[(size_t)r * W + c] = el > 40 || (el < 0 && el > -4) ? -1.0f : 0.0f;
        }
    rs_skyenv env;
    rs_skyenv_info info;
    rs_skyenv_opts o = opts(RS_SKYFILL_MODEL);
    rs_fx_sky_env_opts(&cap, ids, &o, &env, &info);
    const double *eh = info.fill.horizontal_irradiance;
    size_t near = 0, model = 0, bad = 0;
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++) {
            size_t k = (size_t)r * W + c;
            double dep = -asin(rs_pano_pixel_dir(W, H, c, r).z) * 180 / M_PI;
            if (!env.filled[k] || dep <= 0) continue;
            const float *px = env.radiance + 3 * k;
            if (dep < 13) { /* within 10 degrees of the measured 0 to 4, a band's width aside */
                near++;
                bad += env.filled[k] != 1 || fabs(px[1] - 0.4) > 1e-5;
            } else if (dep > 15) {
                model++;
                for (int ch = 0; ch < 3; ch++) bad += fabs(px[ch] - 0.2 * eh[ch] / M_PI) > 1e-5 * eh[ch];
                bad += env.filled[k] != RS_SKYFILL_GROUND_MODEL;
            }
        }
    print_message("filled below the horizon: %zu copy the measured ground, %zu the ground model (%zu in all, E_h "
                  "%.4f %.4f %.4f); %zu wrong\n",
                  near, model, info.fill.ground_model_pixels, eh[0], eh[1], eh[2], bad);
    assert_true(near > 0 && model > 0);
    assert_int_equal(bad, 0);
    assert_true(info.fill.ground_model_pixels >= model && !info.fill.ground_from_albedo);
    double before = env.total_power, rgb[3] = {0.5, 0.6, 0.7};
    rs_err err;
    assert_int_equal(rs_skyenv_set_ground(&env, rgb, 1, &err), (long)info.fill.ground_model_pixels);
    size_t k0 = (size_t)(H - 1) * W; /* straight down: the ground model */
    for (int ch = 0; ch < 3; ch++) assert_true(env.radiance[3 * k0 + ch] == (float)rgb[ch]);
    assert_true(env.total_power > before && env.cdf[(size_t)W * H] == env.total_power);
    /* Without an albedo for the model: the measured band (0.4) at any distance, as before it. */
    double set_power = env.total_power;
    assert_int_equal(rs_skyenv_ground_from_bands(&env, 1, &err), (long)info.fill.ground_model_pixels);
    for (int ch = 0; ch < 3; ch++) assert_true(fabs(env.radiance[3 * k0 + ch] - 0.4) < 1e-5);
    assert_int_equal(env.filled[k0], 1);
    assert_true(env.total_power < set_power && env.cdf[(size_t)W * H] == env.total_power);
    rs_skyenv_release(&env);
    free(ids);
    rs_capture_release(&cap);
}

/* The fill's uncertainty per direction grows with the angle to the nearest measured sky: the
 * angles are right, sigma grows as their square root, and summed over the hidden sky a wall
 * sees it bounds the wall's actual fill error at 2 sigma in every direction. */
static void test_fill_sigma_grows_with_distance(void **state)
{
    (void)state;
    const double sun_az = 30, sun_el = 8;
    rs_capture cap = make_capture(sun_dir(sun_az, sun_el));
    float *ids = courtyard_ids(sun_az);
    size_t npx = (size_t)W * H;
    uint8_t *src = malloc(npx), *tgt = malloc(npx);
    float *dist = malloc(npx * sizeof *dist);
    for (size_t k = 0; k < npx; k++) {
        src[k] = ids[k] < 0;
        tgt[k] = !src[k];
    }
    assert_int_equal(rs_skydist_to_source(W, H, src, tgt, dist, NULL), 0);
    rs_skyenv env;
    rs_skyenv_info info;
    rs_skyenv_opts o = opts(RS_SKYFILL_MODEL);
    rs_fx_sky_env_opts(&cap, ids, &o, &env, &info);
    double rate = rs_skyfill_rate_used(&info.fill, RS_SKYFILL_MODEL);
    print_message("fill uncertainty %.3f per sqrt(radian) (%d blocks)\n", rate, info.fill.cv_folds);
    assert_true(rate > 0);
    /* Opposite the gap the wall hides everything below 40 degrees: the nearest measured sky is
     * straight up, 40 - elevation away (to a grid cell, 2.8 degrees). */
    double az = sun_az + 180, prev = -1;
    for (int el = 30; el >= 0; el -= 10) {
        rs_v3 d = sun_dir(az, el + 0.3);
        int c, r;
        rs_pano_world_to_pixel(&cap.pose, W, H, d, &c, &r);
        size_t k = (size_t)r * W + c;
        double deg = dist[k] * 180 / M_PI;
        print_message("elevation %2d: %.1f deg from the measured sky, fill sigma %.3f\n", el, deg,
                      env.fill_sigma_px[k]);
        assert_true(fabs(deg - (40 - el)) < 3.0);
        assert_true(env.filled[k] && env.fill_sigma_px[k] > prev && env.fill_sigma_px[k] <= 1);
        if (env.fill_sigma_px[k] < 1) assert_float_equal(env.fill_sigma_px[k], rate * sqrt(dist[k]), 0.02 * rate);
        prev = env.fill_sigma_px[k];
    }
    for (size_t k = 0; k < npx; k++)
        if (!env.filled[k]) assert_true(env.fill_sigma_px[k] == 0);
    /* Walls facing every way: the hidden sky's actual error against its summed uncertainty. */
    for (int a = 0; a < 12; a++) {
        double waz = (sun_az + 30 * a) * M_PI / 180;
        rs_v3 n = rs_v3_make(cos(waz), sin(waz), 0);
        double em = 0, et = 0, sig = 0;
        for (int r = 0; r < H; r++)
            for (int c = 0; c < W; c++) {
                size_t k = (size_t)r * W + c;
                rs_v3 d = rs_pano_pixel_dir(W, H, c, r);
                double cs = rs_v3_dot(d, n), om = rs_pano_pixel_solid_angle(W, H, r);
                if (cs <= 0 || !env.filled[k] || d.z <= 0) continue;
                double lm = om * cs * rs_skyenv_luminance(env.radiance + 3 * k);
                em += lm;
                et += om * cs * rs_skyenv_luminance(cap.pano->data + 3 * k);
                sig += lm * env.fill_sigma_px[k];
            }
        print_message("wall facing %5.0f deg: hidden-sky E error %+.4f, sigma %.4f\n", waz * 180 / M_PI, em - et, sig);
        assert_true(fabs(em - et) <= 2 * sig);
    }
    rs_skyenv_release(&env);
    free(src);
    free(tgt);
    free(dist);
    free(ids);
    rs_capture_release(&cap);
}

/* A sky panorama with another rotation and half the exposure covers what the capture cannot
 * see: its pixels are used (scaled back by the exposure found in the overlap), nothing is
 * filled except where it is masked too. */
static void test_sky_panorama(void **state)
{
    (void)state;
    rs_v3 sun = sun_dir(30, 8);
    rs_capture cap = make_capture(sun);
    float *ids = courtyard_ids(30);
    /* Sky panorama: local frame turned 90 degrees about Z (an exact shift of W / 4 columns). */
    rs_capture sky = rs_fx_capture(W, H, NULL, NULL);
    double rot[9] = {0, -1, 0, 1, 0, 0, 0, 0, 1};
    memcpy(sky.pose.rot, rot, sizeof rot);
    uint8_t *mask = malloc((size_t)W * H);
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++) {
            rs_v3 d = rs_pose_dir_to_world(&sky.pose, rs_pano_pixel_dir(W, H, c, r));
            int cc, rr;
            rs_pano_world_to_pixel(&cap.pose, W, H, d, &cc, &rr);
            for (int ch = 0; ch < 3; ch++) rs_image_px(sky.pano, c, r)[ch] = 0.5f * rs_image_px(cap.pano, cc, rr)[ch];
            mask[(size_t)r * W + c] = d.z > -0.2; /* its own model hides the low ground */
        }
    rs_skyenv_opts o = opts(RS_SKYFILL_MODEL);
    o.sky = &sky;
    o.sky_mask = mask;
    rs_skyenv env;
    rs_skyenv_info info;
    rs_fx_sky_env_opts(&cap, ids, &o, &env, &info);
    print_message("sky panorama: %zu pixels used, exposure %.4f %.4f %.4f over %.3f sr, %zu filled\n",
                  info.sky_pano_pixels, info.sky_pano_scale[0], info.sky_pano_scale[1], info.sky_pano_scale[2],
                  info.sky_overlap_sr, env.filled_pixels);
    for (int ch = 0; ch < 3; ch++) assert_true(fabs(info.sky_pano_scale[ch] - 2) < 1e-3);
    size_t bad = 0, filled_upper = 0;
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++) {
            size_t k = (size_t)r * W + c;
            rs_v3 d = rs_pano_pixel_dir(W, H, c, r);
            if (d.z > -0.2) {
                filled_upper += env.filled[k];
                for (int ch = 0; ch < 3; ch++)
                    if (fabs(env.radiance[3 * k + ch] - rs_image_px(cap.pano, c, r)[ch]) >
                        1e-4 * rs_image_px(cap.pano, c, r)[ch])
                        bad++;
            }
        }
    assert_int_equal(filled_upper, 0);
    assert_int_equal(bad, 0);
    assert_true(env.filled_pixels > 0); /* the ground hidden from both */
    rs_skyenv_release(&env);
    free(mask);
    free(ids);
    rs_capture_release(&sky);
    rs_capture_release(&cap);
}

/* Two captures: a second one (exposure 0.8, its own occluder on another side) fills what the
 * first cannot see with its values scaled back; only what both miss is filled, and the first
 * capture's own sky is never replaced. */
static void test_two_captures(void **state)
{
    (void)state;
    rs_v3 sun = sun_dir(30, 8);
    rs_capture cap = make_capture(sun);
    float *ids = courtyard_ids(30);
    rs_capture other = rs_fx_capture(W, H, NULL, NULL);
    uint8_t *mask = malloc((size_t)W * H);
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++) {
            rs_v3 d = rs_pano_pixel_dir(W, H, c, r);
            double az = atan2(d.y, d.x) * 180 / M_PI, el = asin(d.z) * 180 / M_PI;
            for (int ch = 0; ch < 3; ch++) rs_image_px(other.pano, c, r)[ch] = 0.8f * rs_image_px(cap.pano, c, r)[ch];
            mask[(size_t)r * W + c] = el > 0 && !(az > 120 && az < 200 && el < 30);
        }
    const rs_capture *others[1] = {&other};
    const uint8_t *masks[1] = {mask};
    rs_skyenv_opts o = opts(RS_SKYFILL_MODEL);
    o.others = others;
    o.other_masks = masks;
    o.nothers = 1;
    rs_skyenv env;
    rs_skyenv_info info;
    rs_fx_sky_env_opts(&cap, ids, &o, &env, &info);
    print_message("second capture: %zu pixels, exposure %.4f %.4f %.4f over %.3f sr\n", info.other_pixels,
                  info.other_scale[0][0], info.other_scale[0][1], info.other_scale[0][2], info.other_overlap_sr[0]);
    for (int ch = 0; ch < 3; ch++) assert_true(fabs(info.other_scale[0][ch] - 1.25) < 1e-3);
    size_t expect_filled = 0, expect_other = 0, bad = 0;
    for (size_t k = 0; k < (size_t)W * H; k++) {
        int seen1 = ids[k] < 0, seen2 = mask[k];
        expect_filled += !seen1 && !seen2;
        expect_other += !seen1 && seen2;
        if (seen1 || seen2)
            for (int ch = 0; ch < 3; ch++)
                if (fabs(env.radiance[3 * k + ch] - cap.pano->data[3 * k + ch]) > 1e-3 * cap.pano->data[3 * k + ch])
                    bad++;
    }
    assert_int_equal(info.other_pixels, expect_other);
    assert_int_equal(env.filled_pixels, expect_filled);
    assert_int_equal(bad, 0);
    rs_skyenv_release(&env);
    free(mask);
    free(ids);
    rs_capture_release(&other);
    rs_capture_release(&cap);
}

/* A sky whose sun is hidden (nothing within 10 degrees of it is seen) and not given: the search
 * finds it from the glow around it, within 5 degrees. */
static void test_find_hidden_sun(void **state)
{
    (void)state;
    rs_v3 sun = sun_dir(-100, 25);
    rs_skysample *s = malloc(64 * 32 * sizeof *s);
    size_t n = 0;
    for (int r = 0; r < 16; r++)
        for (int c = 0; c < 64; c++) {
            rs_v3 d = rs_pano_pixel_dir(64, 32, c, r);
            if (rs_v3_dot(d, sun) > cos(10 * M_PI / 180)) continue;
            s[n].dir = d;
            truth_sky(d, sun, s[n].rgb);
            s[n].weight = rs_pano_pixel_solid_angle(64, 32, r);
            n++;
        }
    rs_v3 found = rs_skymodel_find_sun(s, n);
    double err_deg = acos(fmin(1, rs_v3_dot(found, sun))) * 180 / M_PI;
    print_message("hidden sun found %.2f degrees off\n", err_deg);
    assert_true(err_deg < 5);
    free(s);
}

/* NREL SPA report (Reda and Andreas 2004, table A4.1): 17 October 2003, 12:30:30 at UTC-7,
 * 39.742476 N 105.1786 W: zenith 50.11162, azimuth 194.34024 degrees. NOAA's equations agree
 * to a few hundredths of a degree. */
static void test_solar_position(void **state)
{
    (void)state;
    double jd, az, el;
    rs_err err;
    assert_int_equal(rs_solar_parse_datetime("2003-10-17T12:30:30-07:00", &jd, &err), 0);
    rs_solar_position(jd, 39.742476, -105.1786, &az, &el);
    print_message("azimuth %.5f zenith %.5f\n", az, 90 - el);
    assert_true(fabs(az - 194.34024) < 0.03);
    assert_true(fabs(90 - el - 50.11162) < 0.03);
    assert_int_equal(rs_solar_parse_datetime("2003-10-17 19:30:30", &jd, &err), 0);
    double az2, el2;
    rs_solar_position(jd, 39.742476, -105.1786, &az2, &el2);
    assert_true(fabs(az2 - az) < 1e-9 && fabs(el2 - el) < 1e-9);
    assert_int_equal(rs_solar_parse_datetime("2003-10-17", &jd, &err), -1);
    assert_non_null(strstr(err.msg, "expected YYYY-MM-DDTHH:MM"));
    /* World frame: north along +Y; a sun due east at 0 elevation lies along +X. */
    rs_v3 d = rs_solar_world_dir(90, 0, 90);
    assert_true(fabs(d.x - 1) < 1e-12 && fabs(d.y) < 1e-12);
}

/* Held-out blocks of a panorama wider than 1024 are measured on a map box-filtered to 1024
 * (skyfill.c, CV_MAX_W): the same sky at 2048 x 1024 gives the held-out errors, the fill's
 * uncertainty rate and the harmonic order that 1024 x 512 gives directly. */
static void test_cv_on_coarser_map(void **state)
{
    (void)state;
    const double sun_az = 30, sun_el = 8;
    double rel[2], rate[2];
    int order[2];
    for (int i = 0; i < 2; i++) {
        W = i ? 2048 : 1024;
        H = W / 2;
        rs_capture cap = make_capture(sun_dir(sun_az, sun_el));
        float *ids = courtyard_ids(sun_az);
        rs_skyenv env;
        rs_skyenv_info info;
        rs_skyenv_opts o = opts(RS_SKYFILL_MODEL);
        rs_fx_sky_env_opts(&cap, ids, &o, &env, &info);
        rel[i] = info.fill.cv_rel_model;
        rate[i] = rs_skyfill_rate_used(&info.fill, RS_SKYFILL_MODEL);
        order[i] = info.fill.model.sh_order;
        print_message("%d x %d: held-out error %.4f, rate %.4f per sqrt(radian), order %d (%d blocks)\n", W, H, rel[i],
                      rate[i], order[i], info.fill.cv_folds);
        assert_int_equal(info.fill.cv_folds, 9);
        rs_skyenv_release(&env);
        free(ids);
        rs_capture_release(&cap);
    }
    W = 512;
    H = 256;
    assert_true(rel[0] > 0 && fabs(rel[1] / rel[0] - 1) < 0.05);
    assert_true(rate[0] > 0 && fabs(rate[1] / rate[0] - 1) < 0.05);
    assert_int_equal(order[1], order[0]);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_low_sun_courtyard), cmocka_unit_test(test_ground_near_bands_and_model),
             cmocka_unit_test(test_fill_sigma_grows_with_distance), cmocka_unit_test(test_cv_on_coarser_map),
             cmocka_unit_test(test_sky_panorama), cmocka_unit_test(test_two_captures),
             cmocka_unit_test(test_find_hidden_sun), cmocka_unit_test(test_solar_position))

/* Several captures of one sky (skyenv.c): where two captures see a direction, the one that saw it
 * more directly wins: mixed pixels at a capture's model silhouette lose against a clean view from
 * another capture, and a coarse panorama against a fine one. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "sky/skyenv.h"
#include "tests/fixtures.h"
#include "tests/testutil.h"

#define W    512
#define H    256
#define WALL 0.1 /* radiance of the model that mixes into silhouette pixels */

/* A smooth sky without a sun (so that nothing is a bright pixel), ground 0.4 below the horizon. */
static void truth_sky(rs_v3 d, double rgb[3])
{
    for (int ch = 0; ch < 3; ch++) rgb[ch] = d.z <= 0 ? 0.4 : (1.0 + 0.1 * ch) * (1 + 0.5 * d.z + 0.2 * d.x);
}

static double el_deg(rs_v3 d)
{
    return asin(d.z) * 180 / M_PI;
}
static double az_deg(rs_v3 d)
{
    return atan2(d.y, d.x) * 180 / M_PI;
}

/* Chebyshev distance (pixels, azimuth wraps, up to 3) from pixel k to the nearest pixel with
 * hidden[] set. */
static int dist_to(const uint8_t *hidden, int w, int h, size_t k)
{
    int r = (int)(k / (size_t)w), c = (int)(k % (size_t)w), best = 3;
    for (int dr = -2; dr <= 2; dr++)
        for (int dc = -2; dc <= 2; dc++) {
            int rr = r + dr < 0 ? 0 : r + dr >= h ? h - 1 : r + dr, d = abs(dr) > abs(dc) ? abs(dr) : abs(dc);
            if (d < best && hidden[(size_t)rr * w + (size_t)((c + dc + w) % w)]) best = d;
        }
    return best;
}

/* A panorama (identity pose) of the truth sky times exposure; pixels next to the hidden ones
 * (hidden = the model in this capture) mixed with the wall as a pixel filter would: half at
 * 1 px, a fifth at 2 px. */
typedef struct {
    int w, h;
    double exposure;
    const uint8_t *hidden;
} capture_view;

static void seen_radiance(rs_v3 d, size_t k, double rgb[3], void *ctx)
{
    const capture_view *v = ctx;
    double mix = 0;
    truth_sky(d, rgb);
    if (v->hidden) {
        int dist = v->hidden[k] ? 0 : dist_to(v->hidden, v->w, v->h, k);
        mix = dist == 0 ? 1 : dist == 1 ? 0.5 : dist == 2 ? 0.2 : 0;
    }
    for (int ch = 0; ch < 3; ch++) rgb[ch] = v->exposure * ((1 - mix) * rgb[ch] + mix * WALL);
}

static rs_capture make_capture(int w, int h, double exposure, const uint8_t *hidden)
{
    capture_view v = {w, h, exposure, hidden};
    return rs_fx_capture(w, h, seen_radiance, &v);
}

static double rel_err(const float *v, const rs_capture *truth_cap, size_t k)
{
    return fabs(rs_skyenv_luminance(v) - rs_skyenv_luminance(truth_cap->pano->data + 3 * k)) /
        rs_skyenv_luminance(truth_cap->pano->data + 3 * k);
}

/* Capture A (the [capture]) stands in a courtyard: walls up to 30 degrees all round. Capture B
 * (exposure 0.8) stands outside: a building hides azimuth 100..140 up to 60 degrees. Each one's
 * pixels next to its own silhouette are mixed with the wall. Where one saw a direction at its
 * silhouette and the other saw it cleanly, the map holds the clean value (scaled to A's
 * exposure): within 1.5 % at 1 px and 4 % at 2 px, 10 and 2.5 times closer than the plain
 * solid-angle mean of the two; where both saw it cleanly the value is A's. */
static void test_silhouette_loses(void **state)
{
    (void)state;
    uint8_t *hid_a = malloc((size_t)W * H), *hid_b = malloc((size_t)W * H);
    float *ids = malloc((size_t)W * H * sizeof *ids);
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++) {
            size_t k = (size_t)r * W + c;
            rs_v3 d = rs_pano_pixel_dir(W, H, c, r);
            double az = az_deg(d), el = el_deg(d);
            hid_a[k] = el < 30;
            hid_b[k] = el < 0 || (az > 100 && az < 140 && el < 60);
            ids[k] = hid_a[k] ? 0.0f : -1.0f;
        }
    rs_capture clean = make_capture(W, H, 1, NULL), a = make_capture(W, H, 1, hid_a);
    rs_capture b = make_capture(W, H, 0.8, hid_b);
    uint8_t *mask_b = malloc((size_t)W * H);
    for (size_t k = 0; k < (size_t)W * H; k++) mask_b[k] = !hid_b[k];
    const rs_capture *others[1] = {&b};
    const uint8_t *masks[1] = {mask_b};
    rs_skyenv_opts o = rs_fx_sky_opts(RS_SKYFILL_ROW);
    o.others = others;
    o.other_masks = masks;
    o.nothers = 1;
    rs_skyenv env;
    rs_skyenv_info info;
    rs_fx_sky_env_opts(&a, ids, &o, &env, &info);
    print_message("exposure %.4f %.4f %.4f over %.3f sr; %zu pixels from B, %zu seen by both\n", info.other_scale[0][0],
                  info.other_scale[0][1], info.other_scale[0][2], info.other_overlap_sr[0], info.other_pixels,
                  info.blended_pixels);
    for (int ch = 0; ch < 3; ch++) assert_true(fabs(info.other_scale[0][ch] - 1.25) < 0.01);
    /* worst error per case: [capture whose silhouette][distance 1, 2]; the plain mean's too */
    double worst[2][3] = {{0}}, plain[2][3] = {{0}}, clean_both = 0;
    size_t n[2][3] = {{0}};
    for (size_t k = 0; k < (size_t)W * H; k++) {
        if (hid_a[k] || hid_b[k]) continue;
        int da = dist_to(hid_a, W, H, k), db = dist_to(hid_b, W, H, k);
        const float *v = env.radiance + 3 * k;
        float mean[3];
        for (int ch = 0; ch < 3; ch++) mean[ch] = 0.5f * (a.pano->data[3 * k + ch] + 1.25f * b.pano->data[3 * k + ch]);
        if (da < 3 && db == 3) {
            worst[0][da] = fmax(worst[0][da], rel_err(v, &clean, k));
            plain[0][da] = fmax(plain[0][da], rel_err(mean, &clean, k));
            n[0][da]++;
        } else if (db < 3 && da == 3) {
            worst[1][db] = fmax(worst[1][db], rel_err(v, &clean, k));
            plain[1][db] = fmax(plain[1][db], rel_err(mean, &clean, k));
            n[1][db]++;
        } else if (da == 3 && db == 3) {
            clean_both = fmax(clean_both, rel_err(v, &a, k));
        }
    }
    for (int s = 0; s < 2; s++)
        for (int d = 1; d <= 2; d++) {
            print_message("%s's silhouette, %d px: %zu pixels, worst error %.2f %% (plain mean %.2f %%)\n",
                          s ? "B" : "A", d, n[s][d], 100 * worst[s][d], 100 * plain[s][d]);
            assert_true(n[s][d] > 100);
            assert_true(worst[s][d] < (d == 1 ? 0.015 : 0.04));
            assert_true((d == 1 ? 10 : 2.5) * worst[s][d] < plain[s][d]);
        }
    print_message("seen cleanly by both: worst difference from A %.2e\n", clean_both);
    assert_true(clean_both < 1e-3);
    /* What A hid and B saw comes from B, at A's exposure (B's silhouette pixels excepted). */
    double worst_hidden = 0;
    for (size_t k = 0; k < (size_t)W * H; k++)
        if (hid_a[k] && !hid_b[k] && dist_to(hid_b, W, H, k) == 3)
            worst_hidden = fmax(worst_hidden, rel_err(env.radiance + 3 * k, &clean, k));
    assert_true(worst_hidden < 1e-3);
    rs_skyenv_release(&env);
    rs_capture_release(&a);
    rs_capture_release(&b);
    rs_capture_release(&clean);
    free(mask_b);
    free(hid_a);
    free(hid_b);
    free(ids);
}

/* Two further captures see what A hides (below 30 degrees): a fine one (same size as A) and a
 * coarse one (half the size) that is 30 % too bright there. The coarse one weighs a quarter per
 * map pixel it lands in: the light of the hidden band is within 2.5 % of the truth, where a plain
 * solid-angle mean (the coarse pixel counting four times) would be off by about 6 %, and a weight
 * of one fine pixel per coarse one by about 4 %. */
static void test_coarse_loses(void **state)
{
    (void)state;
    uint8_t *hid_a = malloc((size_t)W * H);
    float *ids = malloc((size_t)W * H * sizeof *ids);
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++) {
            size_t k = (size_t)r * W + c;
            hid_a[k] = el_deg(rs_pano_pixel_dir(W, H, c, r)) < 30;
            ids[k] = hid_a[k] ? 0.0f : -1.0f;
        }
    rs_capture a = make_capture(W, H, 1, NULL), fine = make_capture(W, H, 1, NULL);
    rs_capture coarse = make_capture(W / 2, H / 2, 1, NULL);
    uint8_t *mask_f = malloc((size_t)W * H), *mask_c = malloc((size_t)W * H / 4);
    for (size_t k = 0; k < (size_t)W * H; k++) mask_f[k] = 1;
    for (int r = 0; r < H / 2; r++)
        for (int c = 0; c < W / 2; c++) {
            mask_c[(size_t)r * (W / 2) + c] = 1;
            if (el_deg(rs_pano_pixel_dir(W / 2, H / 2, c, r)) < 30)
                for (int ch = 0; ch < 3; ch++) rs_image_px(coarse.pano, c, r)[ch] *= 1.3f;
        }
    const rs_capture *others[2] = {&fine, &coarse};
    const uint8_t *masks[2] = {mask_f, mask_c};
    rs_skyenv_opts o = rs_fx_sky_opts(RS_SKYFILL_ROW);
    o.others = others;
    o.other_masks = masks;
    o.nothers = 2;
    rs_skyenv env;
    rs_skyenv_info info;
    rs_fx_sky_env_opts(&a, ids, &o, &env, &info);
    double got = 0, truth = 0;
    for (int r = 0; r < H; r++)
        for (int c = 0; c < W; c++) {
            size_t k = (size_t)r * W + c;
            rs_v3 d = rs_pano_pixel_dir(W, H, c, r);
            if (!hid_a[k] || d.z <= 0) continue;
            double om = rs_pano_pixel_solid_angle(W, H, r);
            got += om * rs_skyenv_luminance(env.radiance + 3 * k);
            truth += om * rs_skyenv_luminance(a.pano->data + 3 * k);
        }
    print_message("hidden band 0..30 degrees: light %.4f against the truth %.4f (%.2f %%)\n", got, truth,
                  100 * (got / truth - 1));
    assert_true(fabs(got / truth - 1) < 0.025);
    assert_true(got > truth); /* the coarse capture still counts */
    rs_skyenv_release(&env);
    rs_capture_release(&a);
    rs_capture_release(&fine);
    rs_capture_release(&coarse);
    free(mask_f);
    free(mask_c);
    free(hid_a);
    free(ids);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_silhouette_loses), cmocka_unit_test(test_coarse_loses))

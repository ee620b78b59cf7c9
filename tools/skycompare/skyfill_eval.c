/* rhoscan-skyfill-eval: how well a sky fill (sky/skyfill.h) recovers sky that no camera saw.
 * A true sky (a real HDR sky, or a reference scene's env.exr) has some of its directions marked
 * hidden: the pixels a facet-id image marks (as the model hides them from the camera), and/or
 * world sectors given on the command line. The sky map is built from the rest exactly as the
 * irradiance stage builds it (rs_skyenv_build_opts) and compared with the truth in the hidden
 * directions above the horizon: the light of the hidden sky, the RMS log error per direction,
 * and the hidden sky's irradiance on vertical walls facing every way. Prints JSON on stdout.
 * A measuring tool for docs/SKY.md, not a stage. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/log.h"
#include "sky/skyenv.h"

static const char *USAGE =
    "usage: rhoscan-skyfill-eval TRUTH_SKY [options]\n"
    "  TRUTH_SKY           equirectangular sky (EXR or Radiance HDR) in the panorama convention\n"
    "  --ids FILE          facet-id image of the same size: pixels >= 0 are hidden (the model's)\n"
    "  --rot R00 .. R22    the panorama's camera-to-world rotation, row major (default identity)\n"
    "  --hide AZ0 AZ1 EL   hide world directions of azimuth AZ0..AZ1 (deg, counter-clockwise\n"
    "                      from +x, wrapping) below elevation EL (deg); repeatable\n"
    "  --fill row|model    the fill method (default model)\n"
    "  --sun AZ EL         the sun's direction is known (deg)\n"
    "  --sh-order N        residual harmonics (default 2, as [sky] sh_order)\n"
    "  --out FILE.exr      write the completed map\n"
    "The truth's sun disc (within 2.5 degrees of its brightest pixel) counts in neither figure\n"
    "'without disc': no sky fill makes a disc (that is [sky] sun_irradiance's or the shadows').\n";

#define MAX_HIDE 16
#define DISC_RAD (2.5 * M_PI / 180)
#define NWALLS   16

typedef struct {
    double az0, az1, el;
} sector;

static int hidden_by_sector(const sector *s, int n, rs_v3 d)
{
    double az = atan2(d.y, d.x) * 180 / M_PI, el = asin(fmax(-1, fmin(1, d.z))) * 180 / M_PI;
    for (int i = 0; i < n; i++) {
        double span = fmod(s[i].az1 - s[i].az0 + 720, 360), rel = fmod(az - s[i].az0 + 720, 360);
        if (rel <= span && el < s[i].el) return 1;
    }
    return 0;
}

static int parse_args(int argc, char **argv, const char **truth, const char **ids, double *rot, sector *hide,
                      int *nhide, int *model, double *sun, int *sun_given, int *sh_order, const char **out)
{
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
#define NEED(k)                                                                             \
    do {                                                                                    \
        if (i + (k) >= argc) {                                                              \
            fprintf(stderr, "rhoscan-skyfill-eval: %s needs %d value(s)\n%s", a, k, USAGE); \
            return -1;                                                                      \
        }                                                                                   \
    } while (0)
        if (strcmp(a, "--ids") == 0) {
            NEED(1);
            *ids = argv[++i];
        } else if (strcmp(a, "--rot") == 0) {
            NEED(9);
            for (int k = 0; k < 9; k++) rot[k] = atof(argv[++i]);
        } else if (strcmp(a, "--hide") == 0) {
            NEED(3);
            if (*nhide == MAX_HIDE) {
                fprintf(stderr, "rhoscan-skyfill-eval: at most %d --hide sectors\n", MAX_HIDE);
                return -1;
            }
            hide[*nhide].az0 = atof(argv[++i]);
            hide[*nhide].az1 = atof(argv[++i]);
            hide[(*nhide)++].el = atof(argv[++i]);
        } else if (strcmp(a, "--fill") == 0) {
            NEED(1);
            *model = strcmp(argv[++i], "row") != 0;
        } else if (strcmp(a, "--sun") == 0) {
            NEED(2);
            sun[0] = atof(argv[++i]);
            sun[1] = atof(argv[++i]);
            *sun_given = 1;
        } else if (strcmp(a, "--sh-order") == 0) {
            NEED(1);
            *sh_order = atoi(argv[++i]);
        } else if (strcmp(a, "--out") == 0) {
            NEED(1);
            *out = argv[++i];
        } else if (a[0] == '-') {
            fprintf(stderr, "rhoscan-skyfill-eval: unknown option %s\n%s", a, USAGE);
            return -1;
        } else
            *truth = a;
#undef NEED
    }
    if (!*truth) {
        fputs(USAGE, stderr);
        return -1;
    }
    return 0;
}

/* The figures over the hidden directions above the horizon. */
static void report(const rs_capture *cap, const rs_skyenv *env, const uint8_t *hidden, const rs_skyenv_info *info)
{
    int w = cap->pano->width, h = cap->pano->height;
    size_t npx = (size_t)w * h, kmax = 0;
    for (size_t k = 0; k < npx; k++)
        if (rs_skyenv_luminance(cap->pano->data + 3 * k) > rs_skyenv_luminance(cap->pano->data + 3 * kmax)) kmax = k;
    rs_v3 disc = rs_pose_dir_to_world(&cap->pose, rs_pano_pixel_dir(w, h, (int)(kmax % w), (int)(kmax / w)));
    double lt = 0, lf = 0, ltd = 0, lfd = 0, sr = 0, lsq = 0, lw = 0;
    double et_all[NWALLS] = {0}, et_h[NWALLS] = {0}, ef_h[NWALLS] = {0};
    for (size_t k = 0; k < npx; k++) {
        int r = (int)(k / w);
        rs_v3 d = rs_pose_dir_to_world(&cap->pose, rs_pano_pixel_dir(w, h, (int)(k % w), r));
        if (d.z <= 0) continue;
        double om = rs_pano_pixel_solid_angle(w, h, r), yt = rs_skyenv_luminance(cap->pano->data + 3 * k);
        double yf = rs_skyenv_luminance(env->radiance + 3 * k);
        int in_disc = rs_v3_dot(d, disc) > cos(DISC_RAD);
        for (int a = 0; a < NWALLS && !in_disc; a++) {
            double az = 2 * M_PI * a / NWALLS, cs = cos(az) * d.x + sin(az) * d.y;
            if (cs <= 0) continue;
            et_all[a] += om * cs * yt;
            if (hidden[k]) {
                et_h[a] += om * cs * yt;
                ef_h[a] += om * cs * yf;
            }
        }
        if (!hidden[k]) continue;
        lt += om * yt;
        lf += om * yf;
        sr += om;
        if (in_disc) continue;
        ltd += om * yt;
        lfd += om * yf;
        if (yt > 0 && yf > 0) {
            double q = log(yf / yt);
            lsq += om * q * q;
            lw += om;
        }
    }
    double worst = 0, mean = 0;
    int worst_a = 0, nw = 0;
    printf("{\n  \"hidden_sr\": %.4f,\n  \"hidden_light_truth\": %.6g,\n  \"hidden_light_fill\": %.6g,\n", sr, lt, lf);
    printf("  \"hidden_light_rel\": %.4f,\n  \"hidden_light_rel_without_disc\": %.4f,\n", lt > 0 ? (lf - lt) / lt : 0,
           ltd > 0 ? (lfd - ltd) / ltd : 0);
    printf("  \"log_rms_without_disc\": %.4f,\n  \"walls\": [", lw > 0 ? sqrt(lsq / lw) : 0);
    for (int a = 0; a < NWALLS; a++) {
        double e = et_all[a] > 0 ? (ef_h[a] - et_h[a]) / et_all[a] : 0;
        printf("%s\n    {\"facing_deg\": %.1f, \"hidden_share\": %.4f, \"error_of_sky_E\": %.4f}", a ? "," : "",
               360.0 * a / NWALLS, et_all[a] > 0 ? et_h[a] / et_all[a] : 0, e);
        if (et_h[a] > 0.02 * et_all[a]) {
            mean += fabs(e);
            nw++;
            if (fabs(e) > fabs(worst)) worst = e, worst_a = a;
        }
    }
    const rs_skyfill_report *f = &info->fill;
    rs_v3 s = f->sun_dir;
    printf("\n  ],\n  \"walls_seeing_hidden_sky\": %d,\n  \"wall_error_mean_abs\": %.4f,\n", nw, nw ? mean / nw : 0);
    printf("  \"wall_error_worst\": %.4f,\n  \"wall_worst_facing_deg\": %.1f,\n", worst, 360.0 * worst_a / NWALLS);
    printf("  \"sun_used_az_deg\": %.2f,\n  \"sun_used_el_deg\": %.2f,\n  \"truth_brightest_az_deg\": %.2f,\n",
           atan2(s.y, s.x) * 180 / M_PI, asin(fmax(-1, fmin(1, s.z))) * 180 / M_PI, atan2(disc.y, disc.x) * 180 / M_PI);
    printf("  \"truth_brightest_el_deg\": %.2f,\n  \"perez_green\": [%.3f, %.3f, %.3f, %.3f, %.3f],\n",
           asin(fmax(-1, fmin(1, disc.z))) * 180 / M_PI, f->model.perez[1][0], f->model.perez[1][1],
           f->model.perez[1][2], f->model.perez[1][3], f->model.perez[1][4]);
    printf("  \"fit_samples\": %zu,\n  \"cv_rel_model\": %.4f,\n  \"cv_rel_row\": %.4f,\n  \"filled_pixels\": %zu\n}\n",
           f->fit_samples, f->cv_rel_model, f->cv_rel_row, env->filled_pixels);
}

int main(int argc, char **argv)
{
    rs_log_init("rhoscan-skyfill-eval");
    const char *truth = NULL, *ids_path = NULL, *out = NULL;
    double rot[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1}, sun[2] = {0, 0};
    sector hide[MAX_HIDE];
    int nhide = 0, model = 1, sun_given = 0, sh_order = 2;
    if (parse_args(argc, argv, &truth, &ids_path, rot, hide, &nhide, &model, sun, &sun_given, &sh_order, &out) != 0)
        return 1;
    rs_err err;
    rs_capture cap;
    memset(&cap, 0, sizeof cap);
    if (!(cap.pano = rs_image_read(truth, &err))) {
        fprintf(stderr, "rhoscan-skyfill-eval: %s\n", err.msg);
        return 1;
    }
    snprintf(cap.path, sizeof cap.path, "%s", truth);
    for (int k = 0; k < 9; k++) cap.pose.rot[k] = rot[k];
    int w = cap.pano->width, h = cap.pano->height;
    size_t npx = (size_t)w * h;
    for (size_t k = 0; k < 3 * npx; k++) /* DWA-compressed skies hold a few slightly negative pixels */
        if (!(cap.pano->data[k] >= 0)) cap.pano->data[k] = 0;
    rs_image *ids = ids_path ? rs_image_read(ids_path, &err) : NULL;
    if (ids_path && (!ids || ids->width != w || ids->height != h)) {
        fprintf(stderr, "rhoscan-skyfill-eval: %s: %s\n", ids_path, ids ? "not the sky's size" : err.msg);
        return 1;
    }
    float *fid = malloc(npx * sizeof *fid);
    uint8_t *hidden = malloc(npx);
    if (!fid || !hidden) return 2;
    for (size_t k = 0; k < npx; k++) {
        rs_v3 d = rs_pose_dir_to_world(&cap.pose, rs_pano_pixel_dir(w, h, (int)(k % w), (int)(k / w)));
        int hid = (ids && ids->data[(size_t)ids->channels * k] >= 0) || hidden_by_sector(hide, nhide, d);
        fid[k] = hid ? 0.0f : -1.0f;
        hidden[k] = (uint8_t)(hid && d.z > 0);
    }
    rs_skyenv_opts o;
    memset(&o, 0, sizeof o);
    o.sun_threshold = 50; /* the stage's defaults ([irradiance] sun_threshold, sun_max_cone_deg 3) */
    o.max_sr = 2 * M_PI * (1 - cos(3 * M_PI / 180));
    o.explicit_sun = 1;
    o.fill.method = model ? RS_SKYFILL_MODEL : RS_SKYFILL_ROW;
    o.fill.sun_mask_rad = 4 * M_PI / 180;
    o.fill.sh_order = sh_order;
    o.fill.sh_ridge = 1e-3;
    o.fill.ground_albedo = 0.2;
    o.fill.cross_validate = 1;
    if (sun_given) {
        double a = sun[0] * M_PI / 180, e = sun[1] * M_PI / 180;
        o.fill.sun_given = 1;
        o.fill.sun_dir = rs_v3_make(cos(e) * cos(a), cos(e) * sin(a), sin(e));
    }
    rs_skyenv env;
    rs_skyenv_info info;
    if (rs_skyenv_build_opts(&cap, fid, &o, &env, &info, &err) != 0) {
        fprintf(stderr, "rhoscan-skyfill-eval: %s\n", err.msg);
        return 2;
    }
    report(&cap, &env, hidden, &info);
    int rc = 0;
    if (out) {
        rs_image img = {.width = w, .height = h, .channels = 3, .data = env.radiance};
        if (rs_image_write(&img, out, NULL, &err) != 0) {
            fprintf(stderr, "rhoscan-skyfill-eval: %s\n", err.msg);
            rc = 2;
        }
    }
    rs_skyenv_release(&env);
    rs_image_free(ids);
    rs_capture_release(&cap);
    free(fid);
    free(hidden);
    return rc;
}

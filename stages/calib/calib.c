/* calib: the capture's calibration before anything looks at its pixels. With [rig], stitches the
 * rig's frames into pano_stitched.exr; with [capture] correspondences, solves the capture's pose
 * from the pairs file, and with [colmap] the poses of the captures it names, into capture_pose.txt.
 * Both are picked up by rs_capture_load. */
#include <stdlib.h>
#include <string.h>
#include <ctype.h>
#include "pipeline/calib_files.h"
#include "calib/calib_math.h"
#include "stages/calib/colmap_poses.h"
#include "stages/calib/edge_pose.h"
#include "common/capture.h"
#include "pipeline/capture_load.h"
#include "pipeline/panorama.h"
#include "common/fileio.h"
#include "common/log.h"
#include "calib/register.h"
#include "calib/cv_adapter.h"
#include "calib/stitch.h"
#include "calib/hdr.h"
#include "calib/response.h"
#include "stages/calib/parallax.h"
#include "stages/stages.h"

/* Solves the pose of [capture] from its pairs file on a width x height panorama and records the
 * residual of every pair, the rejected ones by line. */
static int register_capture(const rs_config *cfg, int width, int height, rs_report *rep, rs_err *err)
{
    char pairs_path[4096], out[4096];
    rs_config_path(cfg, "capture", "correspondences", pairs_path, sizeof pairs_path);
    rs_pair *pairs = NULL;
    rs_v3 *bearing = NULL, *world = NULL;
    double *resid = NULL;
    uint8_t *inlier = NULL;
    int n = 0, rc = -1;
    if (rs_pairs_read(pairs_path, width, height, &pairs, &n, err) != 0) return -1;
    bearing = malloc((size_t)n * sizeof *bearing);
    world = malloc((size_t)n * sizeof *world);
    resid = malloc((size_t)n * sizeof *resid);
    inlier = malloc((size_t)n);
    if (!bearing || !world || !resid || !inlier) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    for (int i = 0; i < n; i++) {
        bearing[i] = rs_pair_bearing(pairs[i].col, pairs[i].row, width, height);
        world[i] = pairs[i].world;
    }
    /* The config's pose, when given, seeds the solver as one more candidate. */
    rs_pose guess;
    double pos[3] = {0, 0, 0};
    int seeded = rs_config_reals(cfg, "capture", "position", pos) == 0;
    rs_config_reals(cfg, "capture", "rotation", guess.rot);
    guess.position = rs_v3_make(pos[0], pos[1], pos[2]);
    rs_register_opts opts = {(int)rs_config_int(cfg, "calib", "ransac_iterations"),
                             rs_config_real(cfg, "calib", "inlier_deg"), (uint64_t)rs_config_int(cfg, "calib", "seed"),
                             seeded ? &guess : NULL};
    rs_register_result res;
    double t0 = rs_now();
    if (rs_register_solve(bearing, world, n, &opts, &res, resid, inlier, err) != 0) {
        /* The solver knows no file: name the pairs file the message is about. */
        rs_err_set_file(err, pairs_path);
        goto out;
    }
    rs_report_time(rep, "registration", rs_now() - t0);
    if (rs_calib_pose_write(rs_work_path(cfg, RS_CALIB_POSE_FILE, out, sizeof out), "capture", &res.pose, err) != 0)
        goto out;

    rs_json *reg = rs_json_set_obj(rep->metrics, "registration");
    rs_json_set_str(reg, "pairs_file", pairs_path);
    rs_json_set_int(reg, "pairs", n);
    rs_json_set_int(reg, "inliers", res.inliers);
    rs_json_set_num(reg, "rms_deg", res.rms_deg);
    rs_json_set_num(reg, "max_deg", res.max_deg);
    rs_calib_pose_json(reg, &res.pose);
    if (seeded) {
        rs_json_set_num(reg, "shift_from_config_m", rs_v3_len(rs_v3_sub(res.pose.position, guess.position)));
        rs_json_set_num(reg, "turn_from_config_deg", rs_calib_rot_angle(res.pose.rot, guess.rot) * 180 / M_PI);
    }
    rs_json *all = rs_json_set_arr(reg, "pairs_by_line");
    for (int i = 0; i < n; i++) {
        rs_json *o = rs_json_push_obj(all);
        rs_json_set_int(o, "line", pairs[i].line);
        rs_json_set_num(o, "residual_deg", resid[i]);
        rs_json_set_bool(o, "inlier", inlier[i]);
        if (!inlier[i])
            rs_report_skip(rep, "correspondence",
                           "%s:%ld: pixel (%g, %g) is %.3f deg from where the pose puts "
                           "(%g, %g, %g): rejected as an outlier",
                           pairs_path, pairs[i].line, pairs[i].col, pairs[i].row, resid[i], pairs[i].world.x,
                           pairs[i].world.y, pairs[i].world.z);
    }
    rs_log_info("calib: pose from %d of %d pairs, residual rms %.4f deg, max %.4f deg; centre (%.4f, %.4f, %.4f)",
                res.inliers, n, res.rms_deg, res.max_deg, res.pose.position.x, res.pose.position.y,
                res.pose.position.z);
    rc = 0;
out:
    free(pairs);
    free(bearing);
    free(world);
    free(resid);
    free(inlier);
    return rc;
}

/* One frame as linear float RGB: EXR, HDR, PNG and JPEG through rs_image_read, TIFF through
 * OpenCV (integer TIFF is sRGB-decoded like PNG). */
static rs_image *read_frame(const char *path, rs_err *err)
{
    const char *dot = strrchr(path, '.');
    char ext[8] = "";
    for (int k = 0; dot && dot[k + 1] && k < 7; k++) ext[k] = (char)tolower((unsigned char)dot[k + 1]);
    rs_image *img = NULL;
    if (strcmp(ext, "tif") == 0 || strcmp(ext, "tiff") == 0) {
        float *data = NULL;
        int w, h, ch, bits;
        char msg[512];
        if (!rs_file_exists(path)) {
            rs_err_errno(err, path, "cannot open the frame");
            return NULL;
        }
        if (rs_cv_image_read(path, &data, &w, &h, &ch, &bits, msg, sizeof msg) != 0) {
            rs_err_set(err, RS_ERR_INPUT, path, 0, "%s", msg);
            return NULL;
        }
        img = rs_image_new(w, h, ch);
        if (img) {
            for (size_t k = 0; k < (size_t)w * h * ch; k++) img->data[k] = bits ? rs_srgb_to_linear(data[k]) : data[k];
        }
        rs_cv_free(data);
        if (!img) rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    } else {
        img = rs_image_read(path, err);
    }
    if (img && img->channels == 1) {
        rs_image *rgb = rs_image_new(img->width, img->height, 3);
        if (rgb)
            for (size_t k = 0; k < (size_t)img->width * img->height; k++)
                rgb->data[3 * k] = rgb->data[3 * k + 1] = rgb->data[3 * k + 2] = img->data[k];
        rs_image_free(img);
        img = rgb;
        if (!img) rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    }
    return img;
}

/* The longest exposure time accepted (s): an hour; anything longer is a typo or a unit slip. */
#define MAX_EXPOSURE_S 3600.0

/* [rig] exposure_times_s: the exposure times of each camera's brackets, in seconds. */
static int exposure_times(const rs_config *cfg, double *times, int max, rs_err *err)
{
    const char *text = rs_config_string(cfg, "rig", "exposure_times_s");
    int n = 0;
    if (!text) {
        /* A response curve only serves to merge brackets: set alone it would be ignored. */
        if (rs_config_has(cfg, "rig", "response_file"))
            return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                              "[rig] response_file is set without [rig] exposure_times_s: expected the brackets' "
                              "exposure times (s) with it, or no response_file");
        return 0;
    }
    for (const char *p = text; *p;) {
        char *end;
        double t = strtod(p, &end);
        if (end == p) {
            while (*p == ' ' || *p == '\t') p++;
            if (!*p) break;
            return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                              "[rig] exposure_times_s = \"%s\": expected exposure times in seconds, > 0, separated "
                              "by spaces",
                              text);
        }
        if (!(t > 0 && t <= MAX_EXPOSURE_S))
            return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                              "[rig] exposure_times_s = \"%s\": time %d is %g: expected a finite time > 0 and at most "
                              "%g s",
                              text, n + 1, t, MAX_EXPOSURE_S);
        if (n == max)
            return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                              "[rig] exposure_times_s = \"%s\": expected 2 to %d times > 0 (s)", text, max);
        times[n++] = t;
        p = end;
    }
    if (n < 2)
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[rig] exposure_times_s = \"%s\": expected at least 2 exposure times (s)", text);
    return n;
}

/* Camera cam's brackets (frames cam * n .. cam * n + n - 1, 8-bit files read as stored codes)
 * merged into radiance; the clipping is reported. */
static rs_image *merge_brackets(const rs_config *cfg, const rs_rig_camera *c, int cam, const double *times, int n,
                                const float *response, rs_report *rep, rs_json *hdr_json, rs_err *err)
{
    rs_image *shots[16] = {NULL}, *merged = NULL;
    char path[4096], msg[512];
    for (int e = 0; e < n; e++) {
        rs_config_path_at(cfg, "rig", "frames", cam * n + e, path, sizeof path);
        float *data = NULL;
        int w, h, ch, bits;
        if (!rs_file_exists(path)) {
            rs_err_errno(err, path, "cannot open the frame");
            goto out;
        }
        if (rs_cv_image_read(path, &data, &w, &h, &ch, &bits, msg, sizeof msg) != 0) {
            rs_err_set(err, RS_ERR_INPUT, path, 0, "%s", msg);
            goto out;
        }
        if (bits != 8 || ch != 3 || w != c->width || h != c->height) {
            rs_err_set(err, RS_ERR_INPUT, path, 0,
                       "bracket is %d x %d, %d channel%s, %s: expected %d x %d 8-bit RGB "
                       "(camera %d, %s)",
                       w, h, ch, ch == 1 ? "" : "s", bits ? "integer" : "float", c->width, c->height, cam, c->name);
            rs_cv_free(data);
            goto out;
        }
        shots[e] = rs_image_new(w, h, 3);
        if (shots[e]) memcpy(shots[e]->data, data, (size_t)w * h * 3 * sizeof(float));
        rs_cv_free(data);
        if (!shots[e]) {
            rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
            goto out;
        }
    }
    rs_hdr_report hr;
    if (rs_hdr_merge((const rs_image *const *)shots, times, n, response, &merged, &hr, err) != 0) goto out;
    rs_json *o = rs_json_set_obj(hdr_json, c->name);
    rs_json_set_int(o, "clipped_pixels", (long long)hr.clipped_px);
    rs_json_set_bool(o, "sun_clipped", hr.sun_clipped);
    if (hr.sun_clipped) {
        rs_v3 d;
        rs_json_set_num(o, "sun_x", hr.sun_x);
        rs_json_set_num(o, "sun_y", hr.sun_y);
        rs_json_set_int(o, "sun_pixels", (long long)hr.sun_px);
        if (rs_rig_unproject(c, hr.sun_x, hr.sun_y, &d)) {
            rs_v3 dr = rs_m3_mul_v(c->r_rig_cam, d);
            rs_json_set_num(o, "sun_elevation_deg_rig", asin(fmax(-1, fmin(1, dr.z))) * 180 / M_PI);
            rs_json_set_num(o, "sun_azimuth_deg_rig", atan2(dr.y, dr.x) * 180 / M_PI);
        }
        rs_report_skip(rep, "sun radiance",
                       "camera %s: the sun is clipped in every exposure (%zu pixels "
                       "around (%.1f, %.1f)): its radiance there is a lower bound; [sky] sun_irradiance (e.g. "
                       "from a pyrheliometer) makes the sun an explicit source",
                       c->name, hr.sun_px, hr.sun_x, hr.sun_y);
    }
out:
    for (int e = 0; e < n; e++) rs_image_free(shots[e]);
    return merged;
}

/* [rig]: the rig file and its frames -> the stitched panorama at out_path; with [rig] parallax,
 * the model and the rig's pose (pose_solved: the calib stage has written the capture's pose). */

/* Gains an overlap cannot support: a pair's samples spread this much (log ratio) or the pairs
 * disagreeing around the rig by this much mean bad overlaps (misregistration, flare, moving
 * content), and the user should look before trusting the scene's brightness. */
#define GAIN_SPREAD_WARN   0.25
#define GAIN_RESIDUAL_WARN 0.02

/* metrics.stitch: each camera's gain source, each pair's robust ratio, spread and residual. */
static void report_gains(rs_json *st, const rs_rig *rig, const rs_gain_report *g, int estimated)
{
    rs_json *src = rs_json_set_obj(st, "gain_source");
    for (int i = 0; i < rig->count; i++)
        rs_json_set_str(src, rig->cams[i].name, rig->cams[i].gain > 0 ? "rig file" : estimated ? "overlaps" : "none");
    if (!estimated) return;
    rs_json_set_num(st, "gain_residual_rms", g->residual_rms);
    rs_json *arr = rs_json_set_arr(st, "gain_pairs");
    for (int p = 0; p < g->npairs; p++) {
        const rs_gain_pair *q = &g->pairs[p];
        rs_json *o = rs_json_push_obj(arr);
        rs_json_set_str(o, "a", rig->cams[q->i].name);
        rs_json_set_str(o, "b", rig->cams[q->j].name);
        rs_json_set_int(o, "samples", (long long)q->samples);
        rs_json_set_num(o, "log_ratio", q->log_ratio);
        rs_json_set_num(o, "spread", q->spread);
        rs_json_set_num(o, "inlier_share", q->inlier);
        rs_json_set_num(o, "residual", q->residual);
        if (q->spread > GAIN_SPREAD_WARN)
            rs_log_warn("calib: cameras %s and %s disagree pixel by pixel in their overlap (spread %.2f in log "
                        "ratio over %zu pixels): check the rig's registration and the frames for flare",
                        rig->cams[q->i].name, rig->cams[q->j].name, q->spread, q->samples);
    }
    if (g->residual_rms > GAIN_RESIDUAL_WARN)
        rs_log_warn("calib: the cameras' gain ratios disagree around the rig by %.1f %% (RMS): the estimated gains "
                    "may be off by as much; give known gains in the rig file (gain:) if you have them",
                    100 * g->residual_rms);
}

static int stitch_rig(const rs_config *cfg, const char *out_path, int pose_solved, rs_report *rep, rs_err *err)
{
    char rig_path[4096], path[4096];
    rs_config_path(cfg, "rig", "file", rig_path, sizeof rig_path);
    rs_rig rig;
    if (rs_rig_load(rig_path, &rig, err) != 0) return -1;
    int nframes = rs_config_path_count(cfg, "rig", "frames"), rc = -1;
    rs_image **frames = calloc((size_t)rig.count, sizeof *frames);
    double *gains = calloc((size_t)rig.count, sizeof *gains);
    rs_image *pano = NULL;
    rs_parallax_model model = {0};
    rs_stitch_stats stats = {0};
    if (!frames || !gains) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    double times[16];
    int nexp = exposure_times(cfg, times, 16, err);
    if (nexp < 0) goto out;
    if (nexp == 0 && nframes != rig.count) {
        rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                   "[rig] frames lists %d image%s but %s has %d camera%s: expected one frame per camera, in "
                   "the order of the rig file",
                   nframes, nframes == 1 ? "" : "s", rig_path, rig.count, rig.count == 1 ? "" : "s");
        goto out;
    }
    if (nexp > 0 && nframes != rig.count * nexp) {
        rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                   "[rig] frames lists %d images but %s has %d cameras and [rig] exposure_times_s gives %d "
                   "exposures: expected %d frames, each camera's exposures together, in the order of the times",
                   nframes, rig_path, rig.count, nexp, rig.count * nexp);
        goto out;
    }
    rs_json *hdr_json = nexp ? rs_json_set_obj(rep->metrics, "hdr") : NULL;
    /* [rig] response_file: one measured curve for every camera instead of Debevec's fit. */
    float response[256 * 3];
    int have_response = nexp && rs_config_path(cfg, "rig", "response_file", path, sizeof path);
    if (have_response && rs_response_read(path, response, err) != 0) goto out;
    if (have_response) rs_json_set_str(hdr_json, "response_file", path);
    for (int i = 0; i < rig.count; i++) {
        rs_config_path_at(cfg, "rig", "frames", nexp ? i * nexp : i, path, sizeof path);
        frames[i] = nexp
            ? merge_brackets(cfg, &rig.cams[i], i, times, nexp, have_response ? response : NULL, rep, hdr_json, err)
            : read_frame(path, err);
        if (!frames[i]) goto out;
        if (frames[i]->width != rig.cams[i].width || frames[i]->height != rig.cams[i].height) {
            rs_err_set(err, RS_ERR_INPUT, path, 0, "frame is %d x %d but camera %d (%s) of %s is %d x %d",
                       frames[i]->width, frames[i]->height, i, rig.cams[i].name, rig_path, rig.cams[i].width,
                       rig.cams[i].height);
            goto out;
        }
    }
    int width = rs_stitch_width(&rig, (int)rs_config_int(cfg, "rig", "width"));
    int use_model = rs_calib_parallax_load(cfg, pose_solved, &model, err);
    if (use_model < 0) goto out;
    rs_stitch_opts opts = {width, rs_config_real(cfg, "rig", "feather_px"), rs_config_bool(cfg, "rig", "gain"),
                           model.scene, model.pose};
    if (rs_stitch(&rig, frames, &opts, &pano, gains, &stats, err) != 0) goto out;
    static const char *const names[] = {"R", "G", "B"};
    if (rs_image_write_exr(pano, out_path, names, 0,
                           use_model ? "rhoscan calib: stitched from [rig] frames "
                                       "(parallax corrected with the model's depth)"
                                     : "rhoscan calib: stitched from [rig] "
                                       "frames (infinite depth)",
                           err) != 0)
        goto out;
    rs_json *st = rs_json_set_obj(rep->metrics, "stitch");
    rs_json_set_str(st, "rig_file", rig_path);
    rs_json_set_int(st, "cameras", rig.count);
    rs_json_set_int(st, "width", width);
    rs_json_set_num(st, "coverage_of_sphere", stats.coverage);
    rs_json_set_int(st, "overlapping_camera_pairs", stats.overlap_pairs);
    rs_json *g = rs_json_set_obj(st, "gains");
    double max_offset = 0;
    for (int i = 0; i < rig.count; i++) {
        rs_json_set_num(g, rig.cams[i].name, gains[i]);
        max_offset = fmax(max_offset, rs_v3_len(rig.cams[i].t_rig_cam));
    }
    rs_json_set_num(st, "max_camera_offset_m", max_offset);
    report_gains(st, &rig, &stats.gain, rs_config_bool(cfg, "rig", "gain"));
    rs_json_set_bool(st, "parallax_corrected", use_model);
    if (use_model) {
        rs_json_set_num(st, "model_depth_coverage_of_sphere", stats.model_coverage);
        rs_json_set_num(st, "hidden_camera_samples_share", stats.hidden_share);
    }
    rs_log_info("calib: stitched %d frames into %d x %d, %.1f %% of the sphere covered", rig.count, width, width / 2,
                100 * stats.coverage);
    /* Parallax not corrected: say how large the ignored offsets are and why. */
    if (max_offset > 0 && !use_model)
        rs_report_skip(rep, "parallax correction",
                       "cameras sit up to %.3f m from the rig centre; stitching assumes "
                       "infinite depth (%s), so near objects may show seams",
                       max_offset, model.why);
    rc = 0;
out:
    for (int i = 0; frames && i < rig.count; i++) rs_image_free(frames[i]);
    free(frames);
    free(gains);
    rs_image_free(pano);
    rs_gain_report_free(&stats.gain);
    rs_calib_parallax_release(&model);
    rs_rig_release(&rig);
    return rc;
}

/* The size of the capture's panorama: the stitched one or [capture] panorama. */
static int panorama_size(const rs_config *cfg, int *width, int *height, rs_err *err)
{
    char path[4096];
    int found = rs_capture_panorama_path(cfg, "capture", path, sizeof path, err);
    if (found < 0) return -1;
    if (!found)
        return rs_err_set(err, RS_ERR_INPUT, rs_config_file(cfg), 0,
                          "[capture] correspondences is set but there is no panorama: expected [capture] panorama "
                          "or [rig] file and frames");
    rs_image *img = rs_image_read(path, err);
    if (!img) return -1;
    *width = img->width;
    *height = img->height;
    rs_image_free(img);
    return 0;
}

int rs_calib_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    char path[4096];
    int have_rig = rs_config_has(cfg, "rig", "file");
    int have_pairs = rs_config_has(cfg, "capture", "correspondences");
    if (rs_capture_panorama_check(cfg, err) != 0) return -1;
    if (have_rig) {
        double t0 = rs_now();
        if (stitch_rig(cfg, rs_work_path(cfg, RS_CALIB_PANO_FILE, path, sizeof path), 0, rep, err) != 0) return -1;
        rs_report_time(rep, "stitch", rs_now() - t0);
    }
    /* A pose left from an earlier run must not outlive the pairs or the [colmap] section that made it. */
    remove(rs_work_path(cfg, RS_CALIB_POSE_FILE, path, sizeof path));
    if (have_pairs) {
        int w = 0, h = 0;
        if (panorama_size(cfg, &w, &h, err) != 0) return -1;
        if (register_capture(cfg, w, h, rep, err) != 0) return -1;
    }
    if (rs_calib_colmap_run(cfg, rep, err) != 0) return -1;
    /* Edges refine the pose solved above (or the config's rough one) before anything uses it. */
    if (rs_calib_edge_pose_run(cfg, rep, err) != 0) return -1;
    /* The pose solved from the first (infinite-depth) stitch places the model: stitch again with
     * the model's depth. */
    if (have_rig && rs_calib_pose_solved(cfg, "capture") && rs_calib_parallax_wanted(cfg)) {
        double t0 = rs_now();
        if (stitch_rig(cfg, rs_work_path(cfg, RS_CALIB_PANO_FILE, path, sizeof path), 1, rep, err) != 0) return -1;
        rs_report_time(rep, "stitch_with_model", rs_now() - t0);
    }
    if (!have_rig && !have_pairs && !rs_config_has(cfg, "colmap", "model") &&
        !rs_config_has(cfg, "capture", "refine_edges"))
        rs_report_skip(rep, "calibration",
                       "no [rig] file, no [capture] correspondences and no [colmap] model: nothing to "
                       "calibrate");
    return 0;
}

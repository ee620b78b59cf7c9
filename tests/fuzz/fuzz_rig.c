/* fuzz_rig: libFuzzer harness for rhoscan's checks of a rig file's values (rs_rig_check). OpenCV
 * parses the YAML (third-party, not fuzzed here); the input becomes the cameras it would return:
 * sizes, models, matrices, distortion, rotations and translations, each value a special one
 * (0, 1, -1, NaN, +-inf, huge, tiny) or raw bits. A rig that passes is then used the way the
 * stitcher uses it (projection and its inverse), which must stay finite and end. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calib/rig.h"

typedef struct {
    const uint8_t *p, *end;
} cursor;

static uint8_t next_byte(cursor *c)
{
    return c->p < c->end ? *c->p++ : 0;
}

static double next_value(cursor *c)
{
    static const double special[] = {0, 1, -1, 0.5, 1e300, -1e300, 1e-300, 65536, 4294967296.0, 2147483648.0};
    uint8_t tag = next_byte(c);
    if (tag < 10) return special[tag];
    if (tag == 10) return NAN;
    if (tag == 11) return INFINITY;
    if (tag == 12) return -INFINITY;
    if (tag < 128) return (double)(tag - 64); /* small integers */
    double v = 0;
    if (c->end - c->p >= 8) { /* raw bits */
        memcpy(&v, c->p, 8);
        c->p += 8;
    }
    return v;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const char *const models[] = {"pinhole", "fisheye", "equirectangular"};
    cursor c = {data, data + size};
    int n = 1 + next_byte(&c) % 4, declared = (int)next_byte(&c) - 2; /* -1: none given */
    if (declared < -1) declared = -1;
    rs_cv_camera cams[4];
    memset(cams, 0, sizeof cams);
    for (int i = 0; i < n; i++) {
        rs_cv_camera *k = &cams[i];
        snprintf(k->name, sizeof k->name, "cam%d", i);
        snprintf(k->model, sizeof k->model, "%s", models[next_byte(&c) % 3]);
        k->has_width = next_byte(&c) % 3;
        k->width = next_value(&c);
        k->has_height = next_byte(&c) % 3;
        k->height = next_value(&c);
        k->has_matrix = next_byte(&c) & 1;
        for (int j = 0; j < 9; j++) k->camera_matrix[j] = next_value(&c);
        k->distortion_count = next_byte(&c) % 9;
        for (int j = 0; j < k->distortion_count; j++) k->distortion[j] = next_value(&c);
        k->has_rotation = next_byte(&c) & 1;
        for (int j = 0; j < 9; j++) k->r_rig_cam[j] = next_value(&c);
        k->has_translation = next_byte(&c) & 1;
        for (int j = 0; j < 3; j++) k->t_rig_cam[j] = next_value(&c);
    }
    rs_err err;
    rs_rig rig;
    if (rs_rig_check("fuzz.yaml", cams, n, declared, &rig, &err) != 0) return 0;
    for (int i = 0; i < rig.count; i++) {
        const rs_rig_camera *cam = &rig.cams[i];
        if (!(cam->max_field > 0) || cam->width < 1 || cam->height < 1) abort();
        for (int k = 0; k < 16; k++) {
            double a = k * 0.39, x, y, margin;
            rs_v3 d = rs_v3_make(sin(a) * 0.7, cos(a) * 0.3, cos(a * 0.5));
            if (rs_rig_project(cam, d, &x, &y, &margin) && !(isfinite(x) && isfinite(y))) abort();
            rs_v3 back;
            if (rs_rig_unproject(cam, (k % 4) * cam->width / 3.0, (k / 4) * cam->height / 3.0, &back) &&
                !isfinite(back.x + back.y + back.z))
                abort();
        }
    }
    rs_rig_release(&rig);
    return 0;
}

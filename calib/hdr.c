/* hdr: exposure brackets -> radiance (see hdr.h). OpenCV does the merge; what is ours is the
 * clipping: Debevec's weights give a clipped pixel the value of its shortest exposure, a lower
 * bound, so such pixels are counted and the sun (a small compact blob of them) is reported. */
#include "calib/hdr.h"

#include <stdlib.h>
#include <string.h>
#include "calib/cv_adapter.h"

#define SATURATED_CODE 250

/* Largest 4-connected blob of marked pixels (flood fill with an explicit stack). */
static size_t largest_blob(const unsigned char *mark, int w, int h, double *cx, double *cy)
{
    size_t n = (size_t)w * h, best = 0;
    int *label = calloc(n, sizeof *label), *stack = malloc(n * sizeof *stack);
    if (!label || !stack) {
        free(label);
        free(stack);
        return 0;
    }
    int next = 0;
    for (size_t s = 0; s < n; s++) {
        if (!mark[s] || label[s]) continue;
        next++;
        size_t top = 0, area = 0;
        double sx = 0, sy = 0;
        stack[top++] = (int)s;
        label[s] = next;
        while (top) {
            int k = stack[--top], x = k % w, y = k / w;
            area++;
            sx += x;
            sy += y;
            const int nb[4][2] = {{x - 1, y}, {x + 1, y}, {x, y - 1}, {x, y + 1}};
            for (int j = 0; j < 4; j++) {
                if (nb[j][0] < 0 || nb[j][0] >= w || nb[j][1] < 0 || nb[j][1] >= h) continue;
                int q = nb[j][1] * w + nb[j][0];
                if (mark[q] && !label[q]) {
                    label[q] = next;
                    stack[top++] = q;
                }
            }
        }
        if (area > best) {
            best = area;
            *cx = sx / area;
            *cy = sy / area;
        }
    }
    free(label);
    free(stack);
    return best;
}

int rs_hdr_merge(const rs_image *const *brackets, const double *times_s, int count, const float *response,
                 rs_image **out, rs_hdr_report *report, rs_err *err)
{
    *out = NULL;
    memset(report, 0, sizeof *report);
    if (count < 2) return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "%d exposure: expected at least 2 to merge", count);
    int w = brackets[0]->width, h = brackets[0]->height, shortest = 0;
    for (int i = 0; i < count; i++) {
        if (brackets[i]->width != w || brackets[i]->height != h || brackets[i]->channels != 3)
            return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "exposure %d is %d x %d x %d: expected %d x %d x 3", i,
                              brackets[i]->width, brackets[i]->height, brackets[i]->channels, w, h);
        if (!(times_s[i] > 0))
            return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "exposure time %d is %g s: expected > 0", i, times_s[i]);
        if (times_s[i] < times_s[shortest]) shortest = i;
    }
    size_t n = (size_t)w * h;
    unsigned char **codes = calloc((size_t)count, sizeof *codes);
    float *times = malloc((size_t)count * sizeof *times);
    unsigned char *clipped = calloc(n, 1);
    rs_image *img = rs_image_new(w, h, 3);
    int rc = -1;
    if (!codes || !times || !clipped || !img) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    for (int i = 0; i < count; i++) {
        times[i] = (float)times_s[i];
        if (!(codes[i] = malloc(3 * n))) {
            rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
            goto out;
        }
        for (size_t k = 0; k < 3 * n; k++) {
            float v = brackets[i]->data[k] * 255.0f + 0.5f;
            codes[i][k] = (unsigned char)(v < 0 ? 0 : v > 255 ? 255 : v);
        }
    }
    char msg[512];
    if (rs_cv_merge_debevec((const unsigned char *const *)codes, times, count, w, h, response, img->data, NULL, msg,
                            sizeof msg) != 0) {
        rs_err_set(err, RS_ERR_INTERNAL, NULL, 0, "HDR merge: %s", msg);
        goto out;
    }
    for (size_t k = 0; k < n; k++) {
        const unsigned char *c = codes[shortest] + 3 * k;
        clipped[k] = c[0] >= SATURATED_CODE || c[1] >= SATURATED_CODE || c[2] >= SATURATED_CODE;
        report->clipped_px += clipped[k];
    }
    if (report->clipped_px) {
        double cx = 0, cy = 0;
        size_t area = largest_blob(clipped, w, h, &cx, &cy);
        /* The sun's disc (0.53 deg) with its glare covers a tiny share of any frame; a large
         * clipped area is a bright sky or a white wall, not the sun. */
        if (area > 0 && area < n / 100) {
            report->sun_clipped = 1;
            report->sun_x = cx;
            report->sun_y = cy;
            report->sun_px = area;
        }
    }
    *out = img;
    img = NULL;
    rc = 0;
out:
    for (int i = 0; codes && i < count; i++) free(codes[i]);
    free(codes);
    free(times);
    free(clipped);
    rs_image_free(img);
    return rc;
}

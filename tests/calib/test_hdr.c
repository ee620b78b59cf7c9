/* Tests of HDR merging from brackets (calib/hdr.h): a scene of known radiance photographed
 * through a gamma response at four exposure times merges back to that radiance up to one
 * scale, and its sun, clipped in every exposure, is found where it is. */
#include <math.h>
#include <stdlib.h>
#include "calib/hdr.h"
#include "tests/testutil.h"

static void test_merge_and_clipped_sun(void **state)
{
    (void)state;
    enum { W = 160, H = 120, N = 4 };
    const double times[N] = {1.0 / 1000, 1.0 / 250, 1.0 / 60, 1.0 / 15};
    const double sun_x = 101.3, sun_y = 37.8;
    rs_image *truth = rs_image_new(W, H, 3), *shots[N];
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int ch = 0; ch < 3; ch++) {
                /* a sky-like gradient over two decades, tinted per channel, and a sun 10^4 brighter */
                double v = pow(10, 2.0 * x / W) * (0.6 + 0.2 * ch) * (1 + 0.3 * sin(0.2 * y));
                if (hypot(x - sun_x, y - sun_y) < 3) v = 1e5;
                rs_image_px(truth, x, y)[ch] = (float)v;
            }
    for (int i = 0; i < N; i++) {
        shots[i] = rs_image_new(W, H, 3);
        for (size_t k = 0; k < (size_t)W * H * 3; k++) {
            double e = truth->data[k] * times[i] * 2.0; /* sensor exposure, 1 = full scale */
            double code = floor(255 * pow(fmin(e, 1), 1 / 2.2) + 0.5);
            shots[i]->data[k] = (float)(code / 255);
        }
    }
    rs_image *hdr = NULL;
    rs_hdr_report rep;
    rs_err err = {0};
    assert_int_equal(rs_hdr_merge((const rs_image *const *)shots, times, N, NULL, &hdr, &rep, &err), 0);
    /* One global scale, from the median ratio; then the relative error of unclipped pixels. */
    size_t n = (size_t)W * H * 3, m = 0;
    double *ratio = malloc(n * sizeof *ratio);
    for (size_t k = 0; k < n; k++)
        if (truth->data[k] < 1e4) ratio[m++] = hdr->data[k] / truth->data[k];
    for (size_t i = 1; i < m; i++) /* insertion sort: small */
        for (size_t j = i; j > 0 && ratio[j - 1] > ratio[j]; j--) {
            double t = ratio[j];
            ratio[j] = ratio[j - 1];
            ratio[j - 1] = t;
        }
    double scale = ratio[m / 2];
    size_t bad = 0;
    for (size_t k = 0; k < n; k++)
        if (truth->data[k] < 1e4 && fabs(hdr->data[k] / truth->data[k] / scale - 1) > 0.1) bad++;
    print_message("scale %g, %zu of %zu values off by more than 10 %%; clipped %zu px, sun at (%.1f, %.1f) %zu px\n",
                  scale, bad, m, rep.clipped_px, rep.sun_x, rep.sun_y, rep.sun_px);
    assert_true(bad < m / 50);
    assert_int_equal(rep.sun_clipped, 1);
    assert_true(hypot(rep.sun_x - sun_x, rep.sun_y - sun_y) < 1.0);
    assert_true(rep.sun_px >= 20 && rep.sun_px <= 40); /* the disc: pi 3^2 = 28 pixels */
    free(ratio);
    rs_image_free(hdr);
    /* Too few exposures. */
    assert_int_equal(rs_hdr_merge((const rs_image *const *)shots, times, 1, NULL, &hdr, &rep, &err), -1);
    for (int i = 0; i < N; i++) rs_image_free(shots[i]);
    rs_image_free(truth);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_merge_and_clipped_sun))

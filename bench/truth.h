/* truth: the benchmark's ground truth: a sky (analytic with a sun, or an HDR file), the
 * converged forward solve with a kernel gathered at many more samples than the runs use and an
 * independent seed, and the panorama a camera sees of it (ray cast, 2 x 2 samples per pixel). */
#ifndef RS_BENCH_TRUTH_H
#define RS_BENCH_TRUTH_H

#include "common/err.h"
#include "common/image.h"
#include "bench/scenegen.h"

/* Sky panorama (world frame, W x W/2), 3 channels, linear. hdr_path NULL: a clear sky with a
 * sun (normal irradiance 8, about six times the sky's) at 35 degrees elevation, its pixels
 * supersampled; "overcast": the CIE overcast sky, no sun; else an HDR file, resampled. */
rs_image *rs_bench_sky(int width, const char *hdr_path, rs_err *err);

typedef struct rs_bench_truth {
    size_t nfaces;
    double *rho;          /* 3 per facet: the true albedo */
    double *esky, *G, *L; /* 3 per facet: E_sky, interreflection, outgoing radiance */
    double rays;          /* rays cast for the truth */
    size_t gathered;      /* facets gathered: what the camera sees and what lights it */
    double seconds;
} rs_bench_truth;

/* Gathers the facets the camera sees and every facet that lights them (rs_gather_run) with
 * (samples, sky_samples, sun_samples) rays and `seed`, then solves
 * L = rho E_sky / pi + diag(rho / pi) K L to 1e-9 (facets left out keep L = 0: no pixel shows
 * them and no light path from them reaches one). NULL with *err on failure. */
rs_bench_truth *rs_bench_truth_new(const rs_bench_scene *sc, const rs_image *sky, int samples, int sky_samples,
                                   int sun_samples, uint32_t seed, rs_err *err);
void rs_bench_truth_free(rs_bench_truth *t);

/* The panorama seen from sc->camera (identity rotation): facet radiance where a ray hits a
 * front face, the sky pixel where it escapes; mean of 2 x 2 rays per pixel. */
rs_image *rs_bench_render(const rs_bench_scene *sc, const rs_bench_truth *t, const rs_image *sky, rs_err *err);

#endif

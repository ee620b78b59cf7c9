/* fuzz_colmap: libFuzzer harness for COLMAP text: the input is cameras.txt, images.txt,
 * points3D.txt, the views file and the control points, separated by NUL bytes (which the readers
 * refuse inside a file); the model is read from a folder (rs_colmap_read), the others by path,
 * and the control points located in the model when all of it was accepted. Run by tools/fuzz.sh. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "calib/colmap.h"
#include "tests/fuzz/fuzz_io.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const char *const names[5] = {"cameras.txt", "images.txt", "points3D.txt", "views.txt", "control.txt"};
    const char *paths[5];
    const uint8_t *p = data, *end = data + size;
    for (int k = 0; k < 5; k++) {
        const uint8_t *nul = k < 4 ? memchr(p, 0, (size_t)(end - p)) : NULL;
        const uint8_t *stop = nul ? nul : end;
        paths[k] = fuzz_write(names[k], p, (size_t)(stop - p));
        p = nul ? nul + 1 : end;
    }
    rs_err err;
    rs_colmap_model m;
    rs_colmap_view *views = NULL;
    rs_colmap_control *cps = NULL;
    int nviews = 0, ncps = 0;
    int model_ok = rs_colmap_read(fuzz_dir(), &m, &err) == 0;
    int views_ok = rs_colmap_views_read(paths[3], &views, &nviews, &err) == 0;
    int cps_ok = rs_colmap_controls_read(paths[4], &cps, &ncps, &err) == 0;
    volatile double sum = 0;
    if (model_ok) {
        for (int i = 0; i < m.nimages; i++) sum += m.images[i].centre.x + m.images[i].points2d_with_3d;
        for (int i = 0; i < m.npoints; i++) sum += m.points[i].xyz.z + m.points[i].track;
        for (int i = 0; i < m.ncameras; i++) sum += m.cameras[i].params[m.cameras[i].nparams - 1];
    }
    if (model_ok && views_ok && cps_ok) {
        rs_v3 *xyz = malloc(2 * (size_t)ncps * sizeof *xyz), *world = xyz ? xyz + ncps : NULL;
        if (xyz && rs_colmap_controls_locate(&m, views, nviews, cps, ncps, paths[4], xyz, &err) == 0) {
            for (int i = 0; i < ncps; i++) world[i] = cps[i].world;
            rs_colmap_similarity sim;
            if (rs_colmap_umeyama(ncps, xyz, world, &sim, NULL, &err) == 0) sum += sim.scale + sim.rms_m;
        }
        free(xyz);
    }
    if (model_ok) rs_colmap_release(&m);
    free(views);
    free(cps);
    (void)sum;
    return 0;
}

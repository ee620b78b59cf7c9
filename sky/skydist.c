/* skydist: angular distance of target pixels to the nearest source pixel (see skydist.h), by
 * brute force between grid cells: only source cells on the edge of the source region can be
 * nearest, and there are few of them at 128 x 64. */
#include "sky/skydist.h"

#include <math.h>
#include <stdlib.h>
#include "common/pano.h"

int rs_skydist_to_source(int w, int h, const uint8_t *src, const uint8_t *target, float *out, rs_err *err)
{
    int cw = w < RS_SKYDIST_CELLS_W ? w : RS_SKYDIST_CELLS_W;
    int chh = h < RS_SKYDIST_CELLS_W / 2 ? h : RS_SKYDIST_CELLS_W / 2;
    size_t nc = (size_t)cw * chh;
    uint8_t *csrc = calloc(nc, 1), *ctgt = calloc(nc, 1);
    float *cdist = malloc(nc * sizeof *cdist);
    rs_v3 *dir = malloc(nc * sizeof *dir);
    uint32_t *edge = malloc(nc * sizeof *edge), *ccol = malloc((size_t)w * sizeof *ccol);
    if (!csrc || !ctgt || !cdist || !dir || !edge || !ccol) {
        free(csrc);
        free(ctgt);
        free(cdist);
        free(dir);
        free(edge);
        free(ccol);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0,
                          "out of memory measuring the sky's distance from the measured sky");
    }
    for (int x = 0; x < w; x++) ccol[x] = (uint32_t)((long)x * cw / w); /* each column's cell */
    for (int r = 0; r < h; r++) {
        size_t row = (size_t)r * w, crow = (size_t)((long)r * chh / h) * cw;
        for (int x = 0; x < w; x++) {
            size_t c = crow + ccol[x];
            csrc[c] |= src[row + x] != 0;
            ctgt[c] |= target[row + x] != 0;
        }
    }
    size_t nedge = 0;
    for (int i = 0; i < chh; i++)
        for (int j = 0; j < cw; j++) {
            size_t c = (size_t)i * cw + j;
            dir[c] = rs_pano_uv_to_dir((j + 0.5) / cw, (i + 0.5) / chh);
            if (!csrc[c]) continue;
            /* An edge cell has a non-source neighbour (azimuth wraps; the poles have none). */
            int l = (j + cw - 1) % cw, r = (j + 1) % cw;
            if (!csrc[(size_t)i * cw + l] || !csrc[(size_t)i * cw + r] || (i > 0 && !csrc[c - cw]) ||
                (i + 1 < chh && !csrc[c + cw]))
                edge[nedge++] = (uint32_t)c;
        }
    size_t nsrc = 0;
    for (size_t c = 0; c < nc; c++) nsrc += csrc[c];
#pragma omp parallel for schedule(dynamic, 64)
    for (size_t c = 0; c < nc; c++) {
        if (!ctgt[c] || csrc[c]) {
            cdist[c] = 0;
            continue;
        }
        double best = -1;
        for (size_t e = 0; e < nedge; e++) {
            double d = rs_v3_dot(dir[c], dir[edge[e]]);
            if (d > best) best = d;
        }
        cdist[c] = nsrc ? (float)acos(fmin(1, fmax(-1, best))) : (float)M_PI;
    }
    for (int r = 0; r < h; r++) {
        size_t row = (size_t)r * w, crow = (size_t)((long)r * chh / h) * cw;
        for (int x = 0; x < w; x++) out[row + x] = target[row + x] ? cdist[crow + ccol[x]] : 0;
    }
    free(csrc);
    free(ctgt);
    free(cdist);
    free(dir);
    free(edge);
    free(ccol);
    return 0;
}

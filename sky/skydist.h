/* skydist: how far a filled sky direction lies from the nearest measured one (an angle), which
 * sets how uncertain its fill is: a fill interpolates near the data and extrapolates far from
 * it. Exports rs_skydist_*. */
#ifndef RS_SKYDIST_H
#define RS_SKYDIST_H

#include <stdint.h>
#include "common/err.h"

/* For every pixel k of a w x h map (rs_pano layout) with target[k], the angle in radians from its
 * direction to the nearest pixel with src[k] into out[k]; out[k] = 0 for the other pixels. The
 * angle is measured between cells of a grid of at most RS_SKYDIST_CELLS_W x RS_SKYDIST_CELLS_W / 2
 * (a pixel takes its cell's value; a cell holding any source pixel is at distance 0), so it is
 * good to about one cell (2.8 degrees). With no source pixel at all every target gets pi.
 * Angles do not depend on the map's pose. Returns 0, or -1 out of memory (err set; err may be
 * NULL: a caller in a parallel region names the failure itself). */
#define RS_SKYDIST_CELLS_W 128
int rs_skydist_to_source(int w, int h, const uint8_t *src, const uint8_t *target, float *out, rs_err *err);

#endif

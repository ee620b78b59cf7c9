/* fuzz_ptx: libFuzzer harness for the Leica PTX reader (rs_ptx_read_mem).
 * Built with -DRHOSCAN_FUZZ=ON and clang; run by tools/fuzz.sh. */
#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <stdint.h>

#include "common/ptx.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    rs_err err;
    rs_cloud *c = rs_ptx_read_mem((const char *)data, size, "fuzz.ptx", &err);
    /* Read every point and every scan's grid so that inconsistent counts show up here. */
    volatile double sum = 0.0;
    if (c) {
        for (size_t i = 0; i < c->npoints; i++) {
            for (int j = 0; j < 3; j++) /* the reader's promise: finite and within range, transformed */
                if (!(fabs(c->xyz[3 * i + j]) <= RS_CLOUD_MAX_M)) abort();
            if (c->intensity && !isfinite(c->intensity[i])) abort();
            sum += c->xyz[3 * i] + c->xyz[3 * i + 2] + c->valid[i];
            if (c->intensity) sum += c->intensity[i];
            if (c->rgb) sum += c->rgb[3 * i + 2];
        }
        for (int s = 0; s < c->nscans; s++) {
            const rs_scan *sc = &c->scans[s];
            size_t last = sc->first + (size_t)sc->cols * (size_t)sc->rows;
            if (sc->cols > 0 && sc->rows > 0) sum += c->xyz[3 * (last - 1)];
        }
    }
    rs_cloud_free(c);
    (void)sum;
    return 0;
}

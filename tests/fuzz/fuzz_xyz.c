/* fuzz_xyz: libFuzzer harness for XYZ/CSV text clouds (rs_cloud_read_text): the first byte picks
 * the [ingest] columns map, the rest is the file. Run by tools/fuzz.sh. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "common/cloud.h"
#include "common/cloud_text.h"
#include "tests/fuzz/fuzz_io.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    static const char *const columns[] = {"x y z", "x y z intensity", "x y z r g b", "- x , y z i red green blue",
                                          "nx ny nz x y z"};
    if (size == 0) return 0;
    const char *cols = columns[data[0] % (sizeof columns / sizeof *columns)];
    rs_err err;
    rs_cloud *c = rs_cloud_read_text(fuzz_write("fuzz.xyz", data + 1, size - 1), cols, &err);
    volatile double sum = 0;
    if (c)
        for (size_t i = 0; i < c->npoints; i++) {
            for (int j = 0; j < 3; j++)
                if (!(fabs(c->xyz[3 * i + j]) <= RS_CLOUD_MAX_M)) abort();
            if (c->intensity && !isfinite(c->intensity[i])) abort();
            sum += c->valid[i] + (c->rgb ? c->rgb[3 * i] : 0);
        }
    rs_cloud_free(c);
    (void)sum;
    return 0;
}

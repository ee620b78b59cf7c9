/* fuzz_las: libFuzzer harness for LAS clouds (rs_las_read through the format table, from a
 * file: the reader streams chunks from it). The first byte picks the class filter (odd: keep
 * classes 2 and 6). Every point read (by whichever reader the table picks) must be finite and
 * within RS_CLOUD_MAX_M. Run by tools/fuzz.sh. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "common/cloud_format.h"
#include "common/las.h"
#include "tests/fuzz/fuzz_io.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 1) return 0;
    uint8_t keep[256] = {0};
    keep[2] = keep[6] = 1;
    rs_cloud_read_opts opts = {.las_keep = data[0] & 1 ? keep : NULL};
    rs_err err;
    rs_cloud *c = rs_cloud_read_with(fuzz_write("fuzz.las", data + 1, size - 1), &opts, NULL, &err);
    int is_las = size >= 5 && memcmp(data + 1, "LASF", 4) == 0;
    volatile double sum = 0;
    if (c)
        for (size_t i = 0; i < c->npoints; i++) {
            for (int j = 0; j < 3; j++)
                if (!(fabs(c->xyz[3 * i + j]) <= RS_CLOUD_MAX_M)) abort();
            /* A LAS point is always a return; a file without the LAS magic falls through the
             * table to PTX, whose "0 0 0" lines are no-return points. */
            if (!isfinite(c->intensity[i]) || (is_las && !c->valid[i])) abort();
            sum += c->rgb ? c->rgb[3 * i + 2] : 0;
        }
    rs_cloud_free(c);
    (void)sum;
    return 0;
}

/* fuzz_pcd: libFuzzer harness for PCD clouds: PCL's reader (a file) and rhoscan's checks of what
 * it returns (rs_pcl_read_pcd: fields inside the record, coordinates, intensities). Run by
 * tools/fuzz.sh. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>

#include "common/pcl_bridge.h"
#include "tests/fuzz/fuzz_io.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    rs_err err;
    rs_cloud *c = rs_pcl_read_pcd(fuzz_write("fuzz.pcd", data, size), &err);
    volatile double sum = 0;
    if (c)
        for (size_t i = 0; i < c->npoints; i++) {
            for (int j = 0; j < 3; j++)
                if (!(fabs(c->xyz[3 * i + j]) <= RS_CLOUD_MAX_M)) abort();
            if (c->intensity && !isfinite(c->intensity[i])) abort();
            sum += c->valid[i] + (c->rgb ? c->rgb[3 * i + 2] : 0);
        }
    rs_cloud_free(c);
    (void)sum;
    return 0;
}

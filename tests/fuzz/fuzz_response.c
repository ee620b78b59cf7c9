/* fuzz_response: libFuzzer harness for response-curve files (rs_response_parse: 256 lines of 1 or
 * 3 linear exposures, non-decreasing). Run by tools/fuzz.sh. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include "calib/response.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    rs_err err;
    float out[256 * 3];
    if (rs_response_parse((const char *)data, size, "fuzz.txt", out, &err) == 0)
        for (int k = 0; k < 256 * 3; k++) {
            /* What the reader promises the merge: in range and not decreasing. */
            if (!(out[k] >= (float)RS_RESPONSE_MIN && out[k] <= (float)RS_RESPONSE_MAX)) abort();
            if (k >= 3 && out[k] < out[k - 3]) abort();
        }
    return 0;
}

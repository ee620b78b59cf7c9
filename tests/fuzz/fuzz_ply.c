/* fuzz_ply: libFuzzer harness for the PLY reader (rs_ply_read_mem), ascii and binary.
 * Built with -DRHOSCAN_FUZZ=ON and clang; run by tools/fuzz.sh. */
#include <stddef.h>
#include <stdint.h>

#include "common/ply.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    rs_err err;
    rs_ply *ply = rs_ply_read_mem((const char *)data, size, "fuzz.ply", &err);
    /* Touch every value so that a reader that claims success with short arrays is caught by
     * AddressSanitizer here rather than in a stage. */
    volatile double sum = 0.0;
    if (ply)
        for (int e = 0; e < ply->nelements; e++) {
            const rs_ply_element *el = &ply->elements[e];
            for (int p = 0; p < el->nprops; p++) {
                const rs_ply_prop *pr = &el->props[p];
                size_t n = pr->is_list ? (el->count ? pr->offsets[el->count] : 0) : el->count;
                for (size_t k = 0; k < n; k++) sum += pr->data[k];
            }
        }
    rs_ply_free(ply);
    (void)sum;
    return 0;
}

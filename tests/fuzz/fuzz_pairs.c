/* fuzz_pairs: libFuzzer harness for the pairs file reader (rs_pairs_parse: `column row X Y Z`
 * lines, comments, duplicates). Run by tools/fuzz.sh. */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

#include "calib/register.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    rs_err err;
    rs_pair *pairs = NULL;
    int n = 0;
    /* Touch every pair: a reader that reports more pairs than it filled is caught here. */
    volatile double sum = 0;
    if (rs_pairs_parse((const char *)data, size, "fuzz.txt", 2048, 1024, &pairs, &n, &err) == 0)
        for (int i = 0; i < n; i++) {
            if (!isfinite(pairs[i].col + pairs[i].row + pairs[i].world.x + pairs[i].world.y + pairs[i].world.z))
                abort(); /* the reader promises finite numbers */
            sum += pairs[i].col + pairs[i].world.z + (double)pairs[i].line;
        }
    free(pairs);
    (void)sum;
    return 0;
}

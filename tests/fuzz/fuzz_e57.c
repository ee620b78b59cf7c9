/* fuzz_e57: libFuzzer harness for the E57 reader (rs_e57_read_mem, and every image's blob).
 * Built with -DRHOSCAN_FUZZ=ON and clang; run by tools/fuzz.sh. A mutated page would only ever
 * fail its CRC-32C, so for inputs whose first byte is even the harness makes the input whole
 * pages, sets the header's length and recomputes every page's CRC first: the mutations then reach
 * the XML, the sections and the bytestreams. Odd first bytes keep the checks as they are. */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "common/e57.h"

static void fix_pages(uint8_t *d, size_t n)
{
    uint64_t len = n;
    memcpy(d + 16, &len, 8); /* filePhysicalLength, little-endian (x86-64) */
    for (size_t p = 0; p + 1024 <= n; p += 1024) {
        uint32_t c = rs_e57_crc32c(d + p, 1020);
        d[p + 1020] = (uint8_t)(c >> 24), d[p + 1021] = (uint8_t)(c >> 16);
        d[p + 1022] = (uint8_t)(c >> 8), d[p + 1023] = (uint8_t)c;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    size_t n = size;
    uint8_t *d = malloc(size ? size : 1);
    if (!d) return 0;
    memcpy(d, data, size);
    if (size >= 1024 && !(data[0] & 1)) {
        n = size / 1024 * 1024;
        d[0] = 'A'; /* the signature's first byte, which the parity took */
        fix_pages(d, n);
    }
    rs_err err;
    volatile double sum = 0.0;
    rs_cloud *c = rs_e57_read_mem(d, n, "fuzz.e57", &err);
    if (c) {
        for (size_t i = 0; i < c->npoints; i++) sum += c->xyz[3 * i] + c->xyz[3 * i + 2] + c->valid[i];
        for (int s = 0; s < c->nscans; s++) {
            const rs_scan *sc = &c->scans[s];
            sum += c->xyz[3 * (sc->first + (size_t)sc->cols * (size_t)sc->rows - 1)];
        }
    }
    rs_cloud_free(c);
    rs_e57 *e = rs_e57_open_mem(d, n, "fuzz.e57", &err);
    for (int i = 0; e && i < rs_e57_image_count(e); i++) {
        uint8_t *blob;
        size_t len;
        if (rs_e57_image_blob(e, i, &blob, &len, &err) == 0) {
            if (len) sum += blob[len - 1];
            free(blob);
        }
    }
    rs_e57_close(e);
    free(d);
    (void)sum;
    return 0;
}

/* fuzz_image: libFuzzer harness for the image reader (rs_image_read_mem): OpenEXR, Radiance
 * .hdr (RGBE), PNG and JPEG, told apart by content. Run by tools/fuzz.sh. */
#include <stddef.h>
#include <stdint.h>

#include "common/image.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    rs_err err;
    rs_image *img = rs_image_read_mem(data, size, "fuzz.img", &err);
    /* Read the first and last pixel: a wrong size would be caught by AddressSanitizer. */
    volatile float sum = 0.0f;
    if (img) {
        sum += img->data[0];
        sum += img->data[(size_t)img->width * (size_t)img->height * (size_t)img->channels - 1];
    }
    rs_image_free(img);
    (void)sum;
    return 0;
}

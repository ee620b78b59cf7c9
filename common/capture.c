/* capture: a posed panorama (see capture.h). */
#include "common/capture.h"

void rs_capture_release(rs_capture *cap)
{
    rs_image_free(cap->pano);
    cap->pano = NULL;
}

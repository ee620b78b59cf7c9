/* pano: the equirectangular panorama convention of docs/DESIGN.md, section Frames, written once.
 * Pixel (c, r) of a W x H image has u = (c + 0.5) / W, v = (r + 0.5) / H; continuous pixel
 * coordinates x = u * W, y = v * H (pixel c covers x in [c, c + 1)).
 * azimuth phi = pi * (1 - 2u) = atan2(d_y, d_x); polar angle theta = pi * v from +Z;
 * d = (sin theta cos phi, sin theta sin phi, cos theta) in the panorama's local frame.
 * A capture's pose: world point = position + R * local; world direction = R * d. */
#ifndef RS_PANO_H
#define RS_PANO_H

#include "common/image.h"
#include "common/vec.h"

typedef struct rs_pose {
    rs_v3 position; /* camera centre, world frame, m */
    double rot[9];  /* local -> world, row-major */
} rs_pose;

/* Unit direction (local frame) of texture coordinates u, v in [0, 1]. */
rs_v3 rs_pano_uv_to_dir(double u, double v);
/* Texture coordinates of a direction (need not be unit; the zero vector gives u = v = 0.5). */
void rs_pano_dir_to_uv(rs_v3 d, double *u, double *v);
/* Direction (local) through the centre of pixel (c, r). */
rs_v3 rs_pano_pixel_dir(int width, int height, int c, int r);
/* Solid angle of one pixel of row r (sr): (2 pi / W) * (pi / H) * sin(theta). */
double rs_pano_pixel_solid_angle(int width, int height, int r);

/* World <-> local directions and the pose of a capture. */
static inline rs_v3 rs_pose_dir_to_world(const rs_pose *p, rs_v3 d_local)
{
    return rs_m3_mul_v(p->rot, d_local);
}
static inline rs_v3 rs_pose_dir_to_local(const rs_pose *p, rs_v3 d_world)
{
    return rs_m3_mul_vt(p->rot, d_world);
}

/* Pixel index (c, r) holding the world direction d_world; wraps in azimuth, clamps at the poles. */
void rs_pano_world_to_pixel(const rs_pose *p, int width, int height, rs_v3 d_world, int *c, int *r);

/* Bilinear sample of an image at continuous coordinates (u, v), wrapping in azimuth and
 * clamping at the poles; writes img->channels values. */
void rs_pano_sample(const rs_image *img, double u, double v, float *out);

#endif

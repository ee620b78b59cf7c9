/* pano: equirectangular mapping (see pano.h for the convention). */
#include "common/pano.h"

rs_v3 rs_pano_uv_to_dir(double u, double v)
{
    double sp, cp, st, ct; /* phi = pi (1 - 2 u), theta = pi v */
    rs_sincos_pi(1.0 - 2.0 * u, &sp, &cp);
    rs_sincos_pi(v, &st, &ct);
    return rs_v3_make(st * cp, st * sp, ct);
}

void rs_pano_dir_to_uv(rs_v3 d, double *u, double *v)
{
    double len = rs_v3_len(d);
    if (!(len > 0)) {
        *u = *v = 0.5;
        return;
    }
    double phi = atan2(d.y, d.x); /* (-pi, pi] */
    double ct = d.z / len;
    ct = ct > 1 ? 1 : (ct < -1 ? -1 : ct);
    *u = 0.5 * (1.0 - phi / M_PI); /* [0, 1) */
    *v = acos(ct) / M_PI;
}

rs_v3 rs_pano_pixel_dir(int width, int height, int c, int r)
{
    return rs_pano_uv_to_dir((c + 0.5) / width, (r + 0.5) / height);
}

double rs_pano_pixel_solid_angle(int width, int height, int r)
{
    return (2.0 * M_PI / width) * (M_PI / height) * sin(M_PI * (r + 0.5) / height);
}

void rs_pano_world_to_pixel(const rs_pose *p, int width, int height, rs_v3 d_world, int *c, int *r)
{
    double u, v;
    rs_pano_dir_to_uv(rs_pose_dir_to_local(p, d_world), &u, &v);
    int cc = (int)floor(u * width), rr = (int)floor(v * height);
    cc %= width;
    if (cc < 0) cc += width;
    *c = cc;
    *r = rr < 0 ? 0 : (rr >= height ? height - 1 : rr);
}

void rs_pano_sample(const rs_image *img, double u, double v, float *out)
{
    int w = img->width, h = img->height, nc = img->channels;
    double x = u * w - 0.5, y = v * h - 0.5;
    double fx = floor(x), fy = floor(y);
    double ax = x - fx, ay = y - fy;
    int x0 = (int)fx, y0 = (int)fy;
    int x1 = x0 + 1, y1 = y0 + 1;
    x0 = ((x0 % w) + w) % w;
    x1 = ((x1 % w) + w) % w;
    y0 = y0 < 0 ? 0 : (y0 >= h ? h - 1 : y0);
    y1 = y1 < 0 ? 0 : (y1 >= h ? h - 1 : y1);
    const float *p00 = rs_image_px(img, x0, y0), *p10 = rs_image_px(img, x1, y0);
    const float *p01 = rs_image_px(img, x0, y1), *p11 = rs_image_px(img, x1, y1);
    for (int k = 0; k < nc; k++) {
        double top = p00[k] + ax * (p10[k] - p00[k]);
        double bot = p01[k] + ax * (p11[k] - p01[k]);
        out[k] = (float)(top + ay * (bot - top));
    }
}

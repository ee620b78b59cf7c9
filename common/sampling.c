/* sampling: Owen-scrambled Sobol points and the maps onto hemispheres and triangles. */
#include "common/sampling.h"

rs_v3 rs_cosine_hemisphere(rs_v3 n, double x, double y)
{
    /* Concentric map: (a, b) on the square's ring of radius r goes to angle phi on the disc,
     * phi = (pi / 4) (b / a) when |a| > |b|, else pi / 2 - (pi / 4) (a / b). */
    double a = 2 * x - 1, b = 2 * y - 1, dx, dy, s, c;
    if (a == 0 && b == 0) {
        dx = dy = 0;
    } else if (fabs(a) > fabs(b)) {
        rs_sincos_pi(0.25 * (b / a), &s, &c);
        dx = a * c;
        dy = a * s;
    } else {
        rs_sincos_pi(0.25 * (a / b), &s, &c); /* cos(pi/2 - v) = sin v, sin(pi/2 - v) = cos v */
        dx = b * s;
        dy = b * c;
    }
    double dz = sqrt(fmax(0.0, 1.0 - dx * dx - dy * dy));
    rs_v3 t, bt;
    rs_v3_basis(n, &t, &bt);
    return rs_v3_add(rs_v3_add(rs_v3_scale(t, dx), rs_v3_scale(bt, dy)), rs_v3_scale(n, dz));
}

rs_v3 rs_triangle_point(rs_v3 a, rs_v3 b, rs_v3 c, double x, double y)
{
    double b0, b1;
    if (y > x) {
        b0 = x / 2;
        b1 = y - b0;
    } else {
        b1 = y / 2;
        b0 = x - b1;
    }
    double b2 = 1 - b0 - b1;
    return rs_v3_make(b0 * a.x + b1 * b.x + b2 * c.x, b0 * a.y + b1 * b.y + b2 * c.y, b0 * a.z + b1 * b.z + b2 * c.z);
}

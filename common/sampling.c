/* sampling: Owen-scrambled Sobol points and the maps onto hemispheres and triangles. */
#include "sampling.h"

rs_v3 rs_cosine_hemisphere(rs_v3 n, double x, double y)
{
    double a = 2 * x - 1, b = 2 * y - 1, r, phi;
    if (a == 0 && b == 0) {
        r = 0;
        phi = 0;
    } else if (fabs(a) > fabs(b)) {
        r = a;
        phi = (M_PI / 4) * (b / a);
    } else {
        r = b;
        phi = M_PI / 2 - (M_PI / 4) * (a / b);
    }
    double dx = r * cos(phi), dy = r * sin(phi);
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
    return rs_v3_make(b0 * a.x + b1 * b.x + b2 * c.x, b0 * a.y + b1 * b.y + b2 * c.y,
                      b0 * a.z + b1 * b.z + b2 * c.z);
}

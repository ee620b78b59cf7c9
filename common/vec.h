/* vec: small inline 3-vector and 3x3 matrix math in double precision.
 * Matrices are row-major double[9]; rs_m3_mul_v applies M to a column vector. */
#ifndef RS_VEC_H
#define RS_VEC_H

#include <math.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

typedef struct {
    double x, y, z;
} rs_v3;

static inline rs_v3 rs_v3_make(double x, double y, double z)
{
    rs_v3 v = {x, y, z};
    return v;
}
static inline rs_v3 rs_v3_add(rs_v3 a, rs_v3 b)
{
    return rs_v3_make(a.x + b.x, a.y + b.y, a.z + b.z);
}
static inline rs_v3 rs_v3_sub(rs_v3 a, rs_v3 b)
{
    return rs_v3_make(a.x - b.x, a.y - b.y, a.z - b.z);
}
static inline rs_v3 rs_v3_scale(rs_v3 a, double s)
{
    return rs_v3_make(a.x * s, a.y * s, a.z * s);
}
static inline double rs_v3_dot(rs_v3 a, rs_v3 b)
{
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
static inline rs_v3 rs_v3_cross(rs_v3 a, rs_v3 b)
{
    return rs_v3_make(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline double rs_v3_len(rs_v3 a)
{
    return sqrt(rs_v3_dot(a, a));
}
/* Unit vector along a; the zero vector stays zero. */
static inline rs_v3 rs_v3_norm(rs_v3 a)
{
    double l = rs_v3_len(a);
    return l > 0 ? rs_v3_scale(a, 1.0 / l) : a;
}
/* sin(pi w) and cos(pi w) for |w| <= 1, to within an ulp or so. The reduction to
 * f = w - k / 2 (k = round(2 w), |f| <= 1/4) is exact (Sterbenz), and on |pi f| <= pi / 4 the
 * Taylor series to degree 15 and 16 leave terms below half an ulp. libm's sincos, with its
 * general range reduction, was 8 % of the irradiance stage (perf). */
static inline void rs_sincos_pi(double w, double *s, double *c)
{
    double k = (double)(int)(2 * w + (w >= 0 ? 0.5 : -0.5)), f = w - 0.5 * k, u = M_PI * f, u2 = u * u;
    double sf = u *
        (1 +
         u2 *
             (-1.0 / 6 +
              u2 *
                  (1.0 / 120 +
                   u2 *
                       (-1.0 / 5040 +
                        u2 *
                            (1.0 / 362880 +
                             u2 * (-1.0 / 39916800 + u2 * (1.0 / 6227020800 + u2 * (-1.0 / 1307674368000))))))));
    double cf = 1 +
        u2 *
            (-1.0 / 2 +
             u2 *
                 (1.0 / 24 +
                  u2 *
                      (-1.0 / 720 +
                       u2 *
                           (1.0 / 40320 +
                            u2 *
                                (-1.0 / 3628800 +
                                 u2 * (1.0 / 479001600 + u2 * (-1.0 / 87178291200 + u2 * (1.0 / 20922789888000))))))));
    switch ((int)k & 3) { /* pi w = pi f + k pi / 2 */
    case 0:
        *s = sf;
        *c = cf;
        break;
    case 1:
        *s = cf;
        *c = -sf;
        break;
    case 2:
        *s = -sf;
        *c = -cf;
        break;
    default:
        *s = -cf;
        *c = sf;
        break;
    }
}

static inline rs_v3 rs_v3_from_f(const float *p)
{
    return rs_v3_make(p[0], p[1], p[2]);
}
static inline int rs_v3_finite(rs_v3 a)
{
    return isfinite(a.x) && isfinite(a.y) && isfinite(a.z);
}

static inline rs_v3 rs_m3_mul_v(const double m[9], rs_v3 v)
{
    return rs_v3_make(m[0] * v.x + m[1] * v.y + m[2] * v.z, m[3] * v.x + m[4] * v.y + m[5] * v.z,
                      m[6] * v.x + m[7] * v.y + m[8] * v.z);
}
/* M^T v: the inverse of a rotation. */
static inline rs_v3 rs_m3_mul_vt(const double m[9], rs_v3 v)
{
    return rs_v3_make(m[0] * v.x + m[3] * v.y + m[6] * v.z, m[1] * v.x + m[4] * v.y + m[7] * v.z,
                      m[2] * v.x + m[5] * v.y + m[8] * v.z);
}
/* The rotation of the unit quaternion (w, x, y, z), row-major (Hamilton convention, as COLMAP's
 * and E57's poses write it). */
static inline void rs_m3_from_quat(double w, double x, double y, double z, double r[9])
{
    r[0] = 1 - 2 * (y * y + z * z);
    r[1] = 2 * (x * y - w * z);
    r[2] = 2 * (x * z + w * y);
    r[3] = 2 * (x * y + w * z);
    r[4] = 1 - 2 * (x * x + z * z);
    r[5] = 2 * (y * z - w * x);
    r[6] = 2 * (x * z - w * y);
    r[7] = 2 * (y * z + w * x);
    r[8] = 1 - 2 * (x * x + y * y);
}

static inline void rs_m3_identity(double m[9])
{
    for (int i = 0; i < 9; i++) m[i] = (i % 4 == 0) ? 1.0 : 0.0;
}

/* Orthonormal basis (t, b) around unit normal n (Duff et al. 2017, "Building an
 * orthonormal basis, revisited"): no branch on a threshold, continuous except at n.z = -1. */
static inline void rs_v3_basis(rs_v3 n, rs_v3 *t, rs_v3 *b)
{
    double s = n.z >= 0 ? 1.0 : -1.0;
    double a = -1.0 / (s + n.z);
    double c = n.x * n.y * a;
    *t = rs_v3_make(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    *b = rs_v3_make(c, s + n.y * n.y * a, -n.y);
}

#endif

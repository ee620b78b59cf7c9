/* calib_math: small dense linear algebra for calibration (see calib_math.h). Sizes are tiny
 * (n <= 8), so the plain textbook algorithms are the clearest choice. */
#include "calib/calib_math.h"

#include <string.h>

void rs_calib_sym_eigen(int n, double *a, double *evals, double *evecs)
{
    for (int i = 0; i < n * n; i++) evecs[i] = (i % (n + 1) == 0) ? 1.0 : 0.0;
    for (int sweep = 0; sweep < 64; sweep++) {
        double off = 0, diag = 0;
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++) {
                if (i == j)
                    diag += a[i * n + j] * a[i * n + j];
                else
                    off += a[i * n + j] * a[i * n + j];
            }
        if (off <= 1e-30 * (diag > 0 ? diag : 1)) break;
        for (int p = 0; p < n - 1; p++)
            for (int q = p + 1; q < n; q++) {
                double apq = a[p * n + q];
                if (apq == 0) continue;
                /* The rotation angle that zeroes a[p][q] (Golub & Van Loan, Algorithm 8.4.1). */
                double theta = (a[q * n + q] - a[p * n + p]) / (2 * apq);
                double t = (theta >= 0 ? 1.0 : -1.0) / (fabs(theta) + sqrt(theta * theta + 1));
                double c = 1 / sqrt(t * t + 1), s = t * c;
                for (int k = 0; k < n; k++) {
                    double akp = a[k * n + p], akq = a[k * n + q];
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for (int k = 0; k < n; k++) {
                    double apk = a[p * n + k], aqk = a[q * n + k];
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
                for (int k = 0; k < n; k++) {
                    double vkp = evecs[k * n + p], vkq = evecs[k * n + q];
                    evecs[k * n + p] = c * vkp - s * vkq;
                    evecs[k * n + q] = s * vkp + c * vkq;
                }
            }
    }
    for (int i = 0; i < n; i++) evals[i] = a[i * n + i];
    /* Selection sort, descending, moving eigenvector columns along. */
    for (int i = 0; i < n; i++) {
        int best = i;
        for (int j = i + 1; j < n; j++)
            if (evals[j] > evals[best]) best = j;
        if (best == i) continue;
        double tmp = evals[i];
        evals[i] = evals[best];
        evals[best] = tmp;
        for (int k = 0; k < n; k++) {
            tmp = evecs[k * n + i];
            evecs[k * n + i] = evecs[k * n + best];
            evecs[k * n + best] = tmp;
        }
    }
}

void rs_calib_rot_exp(const double w[3], double r[9])
{
    double th = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    /* Rodrigues' formula; for tiny angles the series keeps it exact to double precision. */
    double a = th > 1e-8 ? sin(th) / th : 1 - th * th / 6;
    double b = th > 1e-8 ? (1 - cos(th)) / (th * th) : 0.5 - th * th / 24;
    double x = w[0], y = w[1], z = w[2];
    r[0] = 1 - b * (y * y + z * z);
    r[1] = -a * z + b * x * y;
    r[2] = a * y + b * x * z;
    r[3] = a * z + b * x * y;
    r[4] = 1 - b * (x * x + z * z);
    r[5] = -a * x + b * y * z;
    r[6] = -a * y + b * x * z;
    r[7] = a * x + b * y * z;
    r[8] = 1 - b * (x * x + y * y);
}

void rs_calib_m3_mul(const double a[9], const double b[9], double out[9])
{
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            out[3 * i + j] = a[3 * i] * b[j] + a[3 * i + 1] * b[3 + j] + a[3 * i + 2] * b[6 + j];
}

double rs_calib_rot_angle(const double a[9], const double b[9])
{
    double tr = 0; /* trace(a^T b) */
    for (int i = 0; i < 9; i++) tr += a[i] * b[i];
    double c = (tr - 1) / 2;
    return acos(c > 1 ? 1 : c < -1 ? -1 : c);
}

static rs_v3 centroid(int n, const rs_v3 *p)
{
    rs_v3 c = {0, 0, 0};
    for (int i = 0; i < n; i++) c = rs_v3_add(c, p[i]);
    return rs_v3_scale(c, 1.0 / n);
}

double rs_calib_spread_ratio(int n, const rs_v3 *p)
{
    if (n < 2) return 0;
    rs_v3 c = centroid(n, p);
    double cov[9] = {0}, ev[3], vec[9];
    for (int i = 0; i < n; i++) {
        rs_v3 d = rs_v3_sub(p[i], c);
        double v[3] = {d.x, d.y, d.z};
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) cov[3 * a + b] += v[a] * v[b];
    }
    rs_calib_sym_eigen(3, cov, ev, vec);
    return ev[0] > 0 ? sqrt(fmax(ev[1], 0) / ev[0]) : 0;
}

int rs_calib_align(int n, const rs_v3 *src, const rs_v3 *dst, int with_scale, double r[9], rs_v3 *t, double *s)
{
    if (n < 3 || rs_calib_spread_ratio(n, src) < 1e-9 || rs_calib_spread_ratio(n, dst) < 1e-9) return -1;
    rs_v3 cs = centroid(n, src), cd = centroid(n, dst);
    double m[9] = {0}, src_var = 0; /* m[a][b] = sum src_a dst_b, centred */
    for (int i = 0; i < n; i++) {
        rs_v3 a = rs_v3_sub(src[i], cs), b = rs_v3_sub(dst[i], cd);
        double va[3] = {a.x, a.y, a.z}, vb[3] = {b.x, b.y, b.z};
        for (int j = 0; j < 3; j++)
            for (int k = 0; k < 3; k++) m[3 * j + k] += va[j] * vb[k];
        src_var += rs_v3_dot(a, a);
    }
    double sxx = m[0], sxy = m[1], sxz = m[2], syx = m[3], syy = m[4], syz = m[5], szx = m[6], szy = m[7], szz = m[8];
    /* Horn's symmetric 4 x 4 matrix: its top eigenvector is the unit quaternion (w, x, y, z). */
    double nm[16] = {sxx + syy + szz, syz - szy, szx - sxz, sxy - syx,       syz - szy,        sxx - syy - szz,
                     sxy + syx,       szx + sxz, szx - sxz, sxy + syx,       -sxx + syy - szz, syz + szy,
                     sxy - syx,       szx + sxz, syz + szy, -sxx - syy + szz};
    double ev[4], vec[16];
    rs_calib_sym_eigen(4, nm, ev, vec);
    rs_m3_from_quat(vec[0], vec[4], vec[8], vec[12], r);
    double scale = 1;
    if (with_scale) {
        double num = 0;
        for (int i = 0; i < n; i++) num += rs_v3_dot(rs_v3_sub(dst[i], cd), rs_m3_mul_v(r, rs_v3_sub(src[i], cs)));
        scale = num / src_var;
        if (!(scale > 0)) return -1;
    }
    *t = rs_v3_sub(cd, rs_v3_scale(rs_m3_mul_v(r, cs), scale));
    if (s) *s = scale;
    return 0;
}

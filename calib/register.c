/* register: spherical PnP for panoramas (see register.h). Minimal samples of 3 pairs are solved
 * exactly (P3P: the three camera distances from the law of cosines), the candidate poses are
 * scored with a truncated quadratic cost (MSAC), and the best is refined on its inliers. */
#include "calib/register.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "calib/calib_math.h"
#include "common/fileio.h"
#include "common/linsolve.h"

rs_v3 rs_pair_bearing(double col, double row, int width, int height)
{
    return rs_pano_uv_to_dir((col + 0.5) / width, (row + 0.5) / height);
}

/* More correspondences than this is not a hand-made or exported pairs file (and the count is
 * kept in an int). */
#define MAX_PAIRS 1000000

/* One line's numbers into v[5]; returns how many were found (6 when more than five), -1 when a
 * token is not a number. */
static int pair_numbers(const char *s, double v[5])
{
    int n = 0;
    for (const char *q = s; *q;) {
        while (*q == ' ' || *q == '\t' || *q == ',') q++;
        if (!*q) break;
        char *end;
        double x = strtod(q, &end);
        if (end == q || (*end && !strchr(" \t,", *end))) return -1;
        if (n < 5) v[n] = x;
        n += n < 6;
        q = end;
    }
    return n;
}

static int cmp_pair(const void *a, const void *b)
{
    const rs_pair *p = *(const rs_pair *const *)a, *q = *(const rs_pair *const *)b;
    double x[5] = {p->col, p->row, p->world.x, p->world.y, p->world.z};
    double y[5] = {q->col, q->row, q->world.x, q->world.y, q->world.z};
    for (int k = 0; k < 5; k++)
        if (x[k] != y[k]) return x[k] < y[k] ? -1 : 1;
    return (p->line > q->line) - (p->line < q->line);
}

/* The same correspondence listed twice weighs twice in the fit: an editing slip, refused. */
static int refuse_duplicates(const char *path, const rs_pair *p, int n, rs_err *err)
{
    const rs_pair **order = malloc((size_t)n * sizeof *order);
    if (!order) return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory");
    for (int i = 0; i < n; i++) order[i] = &p[i];
    qsort(order, (size_t)n, sizeof *order, cmp_pair);
    int rc = 0;
    for (int i = 1; i < n && rc == 0; i++) {
        const rs_pair *a = order[i - 1], *b = order[i];
        if (a->col == b->col && a->row == b->row && a->world.x == b->world.x && a->world.y == b->world.y &&
            a->world.z == b->world.z)
            rc = rs_err_set(err, RS_ERR_INPUT, path, b->line,
                            "the correspondence (%g, %g) <-> (%g, %g, %g) is listed twice (also on line %ld): "
                            "expected each pair once",
                            b->col, b->row, b->world.x, b->world.y, b->world.z, a->line);
    }
    free(order);
    return rc;
}

int rs_pairs_read(const char *path, int width, int height, rs_pair **pairs, int *count, rs_err *err)
{
    char *text = NULL;
    size_t size = 0;
    *pairs = NULL;
    *count = 0;
    FILE *f = fopen(path, "rb");
    if (!f) return rs_err_errno(err, path, "cannot open the pairs file");
    fclose(f);
    if (rs_read_file(path, &text, &size, err) != 0) return -1;
    int rc = rs_pairs_parse(text, size, path, width, height, pairs, count, err);
    free(text);
    return rc;
}

int rs_pairs_parse(const char *data, size_t size, const char *path, int width, int height, rs_pair **pairs, int *count,
                   rs_err *err)
{
    *pairs = NULL;
    *count = 0;
    if (memchr(data, 0, size))
        return rs_err_set(err, RS_ERR_INPUT, path, 0, "contains a NUL byte: expected a text file");
    int n = 0, cap = 0, rc = -1;
    rs_pair *p = NULL;
    long lineno = 0;
    char line[256];
    for (const char *s0 = data, *end = data + size; s0 < end;) {
        const char *nl = memchr(s0, '\n', (size_t)(end - s0)), *le = nl ? nl : end;
        const char *hash = memchr(s0, '#', (size_t)(le - s0));
        const char *s = s0, *ce = hash ? hash : le;
        s0 = nl ? nl + 1 : end;
        lineno++;
        while (s < ce && (*s == ' ' || *s == '\t' || *s == '\r')) s++;
        while (ce > s && (ce[-1] == ' ' || ce[-1] == '\t' || ce[-1] == '\r')) ce--;
        if (s == ce) continue;
        double v[5];
        /* The line NUL-terminated: on the stack, or on the heap when long (padded with blanks). */
        size_t len = (size_t)(ce - s);
        char *text = len < sizeof line ? line : malloc(len + 1);
        if (!text) {
            rs_err_set(err, RS_ERR_SYSTEM, path, lineno, "out of memory");
            goto out;
        }
        memcpy(text, s, len);
        text[len] = 0;
        int got = pair_numbers(text, v);
        if (text != line) free(text);
        if (got != 5) {
            rs_err_set(err, RS_ERR_INPUT, path, lineno, "\"%.*s\": expected `column row X Y Z` (five numbers)",
                       (int)(ce - s) > 80 ? 80 : (int)(ce - s), s);
            goto out;
        }
        static const char *const field[5] = {"the column", "the row", "X", "Y", "Z"};
        for (int k = 0; k < 5; k++)
            if (!isfinite(v[k])) {
                rs_err_set(err, RS_ERR_INPUT, path, lineno, "\"%.*s\": %s is %g: expected finite numbers",
                           (int)len > 80 ? 80 : (int)len, s, field[k], v[k]);
                goto out;
            }
        /* Pixel c covers c - 0.5 .. c + 0.5 (docs/DESIGN.md, section Pairs file). */
        if (v[0] < -0.5 || v[0] >= width - 0.5 || v[1] < -0.5 || v[1] > height - 0.5) {
            rs_err_set(err, RS_ERR_INPUT, path, lineno,
                       "pixel (%g, %g) lies outside the %d x %d panorama: expected column in [-0.5, %g) "
                       "and row in [-0.5, %g]",
                       v[0], v[1], width, height, width - 0.5, height - 0.5);
            goto out;
        }
        if (n == MAX_PAIRS) {
            rs_err_set(err, RS_ERR_INPUT, path, lineno, "more than %d correspondences: expected fewer", MAX_PAIRS);
            goto out;
        }
        if (n == cap) {
            cap = cap ? 2 * cap : 64;
            rs_pair *q = realloc(p, (size_t)cap * sizeof *q);
            if (!q) {
                rs_err_set(err, RS_ERR_SYSTEM, path, lineno, "out of memory");
                goto out;
            }
            p = q;
        }
        p[n++] = (rs_pair){v[0], v[1], rs_v3_make(v[2], v[3], v[4]), lineno};
    }
    if (n < 4) {
        rs_err_set(err, RS_ERR_INPUT, path, 0,
                   "%d correspondence%s: expected at least 4 lines `column row X Y Z` to solve a pose", n,
                   n == 1 ? "" : "s");
        goto out;
    }
    if (refuse_duplicates(path, p, n, err) != 0) goto out;
    *pairs = p;
    *count = n;
    p = NULL;
    rc = 0;
out:
    free(p);
    return rc;
}

double rs_register_residual_deg(const rs_pose *p, rs_v3 b, rs_v3 x)
{
    rs_v3 d = rs_pose_dir_to_local(p, rs_v3_sub(x, p->position));
    double c = rs_v3_len(rs_v3_cross(d, b)), s = rs_v3_dot(d, b);
    return atan2(c, s) * 180 / M_PI;
}

/* P3P on bearings b[0..2] (unit, local) and world points x[0..2]. With the distances s_i from the
 * centre, |s_i b_i - s_j b_j| = |x_i - x_j| for the three pairs. For a given s0 the first two
 * equations give s1 and s2 (two branches each), and the third is a function of s0 whose roots
 * are found by a scan and bisection: simpler and more robust than the quartic's coefficients,
 * and cheap for three points. Then the rigid transform local -> world follows from the three
 * local points. Returns the number of poses written (at most 8). */
static int p3p(const rs_v3 b[3], const rs_v3 x[3], rs_pose out[8])
{
    double d01 = rs_v3_len(rs_v3_sub(x[0], x[1])), d02 = rs_v3_len(rs_v3_sub(x[0], x[2]));
    double d12 = rs_v3_len(rs_v3_sub(x[1], x[2]));
    double c01 = rs_v3_dot(b[0], b[1]), c02 = rs_v3_dot(b[0], b[2]), c12 = rs_v3_dot(b[1], b[2]);
    double sn01 = sqrt(fmax(0, 1 - c01 * c01)), sn02 = sqrt(fmax(0, 1 - c02 * c02));
    if (sn01 < 1e-6 || sn02 < 1e-6 || d01 <= 0 || d02 <= 0 || d12 <= 0) return 0;
    double smax = fmin(d01 / sn01, d02 / sn02);
    int found = 0;
    enum { STEPS = 600 };
    for (int br = 0; br < 4 && found < 8; br++) {
        double g1 = (br & 1) ? -1 : 1, g2 = (br & 2) ? -1 : 1;
        double prev_s0 = 0, prev_f = 0;
        int prev_ok = 0;
        for (int k = 1; k <= STEPS && found < 8; k++) {
            /* sin spacing: dense near smax, where the square roots change fastest. */
            double s0 = smax * sin(0.5 * M_PI * k / STEPS);
            double r1 = d01 * d01 - s0 * s0 * sn01 * sn01, r2 = d02 * d02 - s0 * s0 * sn02 * sn02;
            double s1 = s0 * c01 + g1 * sqrt(fmax(r1, 0)), s2 = s0 * c02 + g2 * sqrt(fmax(r2, 0));
            int ok = s1 > 0 && s2 > 0;
            double f = s1 * s1 + s2 * s2 - 2 * s1 * s2 * c12 - d12 * d12;
            if (ok && prev_ok && (f == 0 || (f > 0) != (prev_f > 0))) {
                double lo = prev_s0, hi = s0, flo = prev_f;
                for (int it = 0; it < 60; it++) {
                    double mid = 0.5 * (lo + hi);
                    double m1 = mid * c01 + g1 * sqrt(fmax(d01 * d01 - mid * mid * sn01 * sn01, 0));
                    double m2 = mid * c02 + g2 * sqrt(fmax(d02 * d02 - mid * mid * sn02 * sn02, 0));
                    double fm = m1 * m1 + m2 * m2 - 2 * m1 * m2 * c12 - d12 * d12;
                    if ((fm > 0) == (flo > 0)) {
                        lo = mid;
                        flo = fm;
                    } else {
                        hi = mid;
                    }
                }
                double r0 = 0.5 * (lo + hi);
                double q1 = r0 * c01 + g1 * sqrt(fmax(d01 * d01 - r0 * r0 * sn01 * sn01, 0));
                double q2 = r0 * c02 + g2 * sqrt(fmax(d02 * d02 - r0 * r0 * sn02 * sn02, 0));
                rs_v3 local[3] = {rs_v3_scale(b[0], r0), rs_v3_scale(b[1], q1), rs_v3_scale(b[2], q2)};
                rs_pose *p = &out[found];
                if (rs_calib_align(3, local, x, 0, p->rot, &p->position, NULL) == 0) found++;
            }
            prev_s0 = s0;
            prev_f = f;
            prev_ok = ok;
        }
    }
    return found;
}

/* MSAC cost: squared residual (radians^2) truncated at the threshold. */
static double msac_cost(const rs_pose *p, const rs_v3 *b, const rs_v3 *x, int n, double thr_rad)
{
    double cost = 0, t2 = thr_rad * thr_rad;
    for (int i = 0; i < n; i++) {
        double r = rs_register_residual_deg(p, b[i], x[i]) * M_PI / 180;
        cost += fmin(r * r, t2);
    }
    return cost;
}

static uint64_t rng_next(uint64_t *s)
{
    /* splitmix64 (Steele, Lea, Flood 2014): deterministic for a seed on every platform. */
    uint64_t z = (*s += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/* Tangent-plane residual (2 numbers, radians for small angles) of one pair. */
static void residual2(const rs_pose *p, rs_v3 b, rs_v3 x, double r[2])
{
    rs_v3 d = rs_v3_norm(rs_pose_dir_to_local(p, rs_v3_sub(x, p->position)));
    rs_v3 t, u;
    rs_v3_basis(b, &t, &u);
    r[0] = rs_v3_dot(d, t);
    r[1] = rs_v3_dot(d, u);
}

/* The pose moved by the 6 parameters: a rotation w (radians, world side) and a shift of the centre. */
static rs_pose pose_step(const rs_pose *p, const double delta[6], double pos_scale)
{
    rs_pose q;
    double dr[9];
    rs_calib_rot_exp(delta, dr);
    rs_calib_m3_mul(dr, p->rot, q.rot);
    q.position = rs_v3_add(p->position, rs_v3_scale(rs_v3_make(delta[3], delta[4], delta[5]), pos_scale));
    return q;
}

static double lm_cost(const rs_pose *p, const rs_v3 *b, const rs_v3 *x, const uint8_t *use, int n)
{
    double c = 0, r[2];
    for (int i = 0; i < n; i++) {
        if (!use[i]) continue;
        residual2(p, b[i], x[i], r);
        c += r[0] * r[0] + r[1] * r[1];
    }
    return c;
}

/* Levenberg-Marquardt on the tangent-plane residuals of the pairs marked in use. The position
 * step is scaled by the points' mean distance so that all six parameters are angles. */
static void refine_lm(rs_pose *pose, const rs_v3 *b, const rs_v3 *x, const uint8_t *use, int n)
{
    double dist = 0;
    int m = 0;
    for (int i = 0; i < n; i++)
        if (use[i]) {
            dist += rs_v3_len(rs_v3_sub(x[i], pose->position));
            m++;
        }
    double scale = m && dist > 0 ? dist / m : 1;
    double lambda = 1e-3, cost = lm_cost(pose, b, x, use, n);
    for (int it = 0; it < 100; it++) {
        double jtj[36] = {0}, jtr[6] = {0};
        for (int i = 0; i < n; i++) {
            if (!use[i]) continue;
            double r0[2], j[2][6];
            residual2(pose, b[i], x[i], r0);
            for (int k = 0; k < 6; k++) {
                double h = 1e-7, dp[6] = {0}, dm[6] = {0}, rp[2], rm[2];
                dp[k] = h;
                dm[k] = -h;
                rs_pose pp = pose_step(pose, dp, scale), pm = pose_step(pose, dm, scale);
                residual2(&pp, b[i], x[i], rp);
                residual2(&pm, b[i], x[i], rm);
                j[0][k] = (rp[0] - rm[0]) / (2 * h);
                j[1][k] = (rp[1] - rm[1]) / (2 * h);
            }
            for (int a = 0; a < 6; a++) {
                jtr[a] += j[0][a] * r0[0] + j[1][a] * r0[1];
                for (int c = 0; c < 6; c++) jtj[6 * a + c] += j[0][a] * j[0][c] + j[1][a] * j[1][c];
            }
        }
        int improved = 0;
        while (!improved && lambda < 1e12) {
            double a[36], delta[6];
            memcpy(a, jtj, sizeof a);
            for (int k = 0; k < 6; k++) {
                a[7 * k] += lambda * (jtj[7 * k] > 0 ? jtj[7 * k] : 1);
                delta[k] = -jtr[k];
            }
            if (rs_solve_dense(a, delta, 6) != 0) {
                lambda *= 10;
                continue;
            }
            rs_pose trial = pose_step(pose, delta, scale);
            double c = lm_cost(&trial, b, x, use, n);
            if (c < cost) {
                double step = 0;
                for (int k = 0; k < 6; k++) step += delta[k] * delta[k];
                *pose = trial;
                cost = c;
                lambda = fmax(lambda / 10, 1e-12);
                improved = 1;
                if (step < 1e-24) return;
            } else {
                lambda *= 10;
            }
        }
        if (!improved) return;
    }
}

static int mark_inliers(const rs_pose *p, const rs_v3 *b, const rs_v3 *x, int n, double thr_deg, uint8_t *in,
                        double *res_deg)
{
    int k = 0;
    for (int i = 0; i < n; i++) {
        res_deg[i] = rs_register_residual_deg(p, b[i], x[i]);
        in[i] = res_deg[i] < thr_deg;
        k += in[i];
    }
    return k;
}

int rs_register_solve(const rs_v3 *bearing, const rs_v3 *world, int n, const rs_register_opts *opts,
                      rs_register_result *res, double *residual_deg, uint8_t *inlier, rs_err *err)
{
    if (n < 4)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "%d correspondences: expected at least 4 to solve a pose", n);
    /* Points on one line leave the rotation about that line undetermined. */
    if (rs_calib_spread_ratio(n, world) < 1e-6)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                          "the %d world points all lie on one line (or coincide): the pose is undetermined; "
                          "expected points spread in at least two directions",
                          n);
    double thr = opts->inlier_deg * M_PI / 180;
    rs_pose best;
    double best_cost = INFINITY;
    if (opts->guess) {
        best = *opts->guess;
        best_cost = msac_cost(&best, bearing, world, n, thr);
    }
    uint64_t rng = opts->seed;
    for (int it = 0; it < opts->iterations; it++) {
        int idx[3];
        idx[0] = (int)(rng_next(&rng) % (uint64_t)n);
        do idx[1] = (int)(rng_next(&rng) % (uint64_t)n);
        while (idx[1] == idx[0]);
        do idx[2] = (int)(rng_next(&rng) % (uint64_t)n);
        while (idx[2] == idx[0] || idx[2] == idx[1]);
        rs_v3 b[3] = {bearing[idx[0]], bearing[idx[1]], bearing[idx[2]]};
        rs_v3 x[3] = {world[idx[0]], world[idx[1]], world[idx[2]]};
        rs_pose cand[8];
        int k = p3p(b, x, cand);
        for (int c = 0; c < k; c++) {
            double cost = msac_cost(&cand[c], bearing, world, n, thr);
            if (cost < best_cost) {
                best_cost = cost;
                best = cand[c];
            }
        }
    }
    if (!isfinite(best_cost))
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                          "no pose fits any 3 of the %d correspondences: expected pixel and world points "
                          "of the same features",
                          n);
    /* Refine on the inliers, re-select with the refined pose, until the set settles. */
    int k = mark_inliers(&best, bearing, world, n, opts->inlier_deg, inlier, residual_deg);
    for (int round = 0; round < 5 && k >= 3; round++) {
        refine_lm(&best, bearing, world, inlier, n);
        uint8_t *before = malloc((size_t)n);
        if (!before) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        memcpy(before, inlier, (size_t)n);
        k = mark_inliers(&best, bearing, world, n, opts->inlier_deg, inlier, residual_deg);
        int same = memcmp(before, inlier, (size_t)n) == 0;
        free(before);
        if (same) break;
    }
    if (k < 4)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                          "only %d of %d correspondences agree on one pose within %g deg: expected at least 4 "
                          "(check the pairs, or raise [calib] inlier_deg)",
                          k, n, opts->inlier_deg);
    rs_v3 *xin = malloc((size_t)k * sizeof *xin);
    if (!xin) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    double sum2 = 0, mx = 0;
    for (int i = 0, j = 0; i < n; i++)
        if (inlier[i]) {
            xin[j++] = world[i];
            sum2 += residual_deg[i] * residual_deg[i];
            mx = fmax(mx, residual_deg[i]);
        }
    double spread = rs_calib_spread_ratio(k, xin);
    free(xin);
    if (spread < 1e-6)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                          "the %d inlying world points lie on one line: the pose is undetermined", k);
    res->pose = best;
    res->inliers = k;
    res->rms_deg = sqrt(sum2 / k);
    res->max_deg = mx;
    return 0;
}

/* albpool: the albedo pooled within same-material planar regions, edges kept (see albpool.h).
 * The candidates are pool.h's same-plane lists with R far beyond the disk (only the plane and the
 * disk of RS_POOL_FACETS facets bound them: the albedo does not change with what the facet sees). */
#include "stages/reflectance/albpool.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "stages/reflectance/pool.h"

/* The plane test of the candidate lists: normals within about 8 degrees (sqrt(1 - cos) < 0.1),
 * off the facet's plane by at most a tenth of the distance. */
#define RS_ALBPOOL_PLANE 0.1

static double lum3(const double *v)
{
    return 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
}

/* The facet's independent relative noise: radiance and Monte Carlo in quadrature. */
static double noise2(const rs_albpool_in *in, size_t j)
{
    return in->s_rad[j] * in->s_rad[j] + in->s_mc[j] * in->s_mc[j];
}

/* Does j's albedo agree with i's within the test's combined standard errors, in every channel?
 * An albedo above 1 (light the model missed, pixels mixed across an edge) is no neighbour. */
static int agrees(const rs_albpool_in *in, size_t i, size_t j)
{
    double s = in->sigmas * sqrt(noise2(in, i) + noise2(in, j) + 2 * in->floor * in->floor);
    for (int ch = 0; ch < 3; ch++) {
        double a = in->rho[3 * i + ch], b = in->rho[3 * j + ch], mid = 0.5 * (a + b);
        if (!(fabs(a - b) <= s * mid) || b > 1) return 0;
    }
    return 1;
}

typedef struct {
    double shrink, kept_share;
} facet_stats;

/* Facet i's pooled albedo and uncertainty parts from its candidate list q0..q1 (itself first).
 * kept/w: scratch of RS_POOL_MAX_NEIGHBOURS. */
static facet_stats pool_facet(const rs_pool *p, const rs_albpool_in *in, size_t i, uint32_t *kept, double *w,
                              rs_albpool_out *out)
{
    facet_stats st = {0, 1};
    size_t q0 = p->start[i], q1 = p->start[i + 1], nk = 0;
    double wsum = 0;
    for (size_t q = q0; q < q1; q++) {
        uint32_t j = p->nbr[q];
        if (j != i && !agrees(in, i, j)) continue;
        /* inverse variance: a facet observed with large noise does not pull a well observed one */
        double wj = p->w[q] / (noise2(in, j) + in->floor * in->floor);
        kept[nk] = j, w[nk] = wj, wsum += wj, nk++;
    }
    if (q1 - q0 > 1) st.kept_share = (double)(nk - 1) / (double)(q1 - q0 - 1);
    double m[3] = {0, 0, 0}, sw2 = 0, N = 0;
    for (size_t k = 0; k < nk; k++) {
        w[k] /= wsum;
        for (int ch = 0; ch < 3; ch++) m[ch] += w[k] * in->rho[3 * (size_t)kept[k] + ch];
        double s2 = noise2(in, kept[k]);
        sw2 += w[k] * w[k];
        N += w[k] * s2 - w[k] * w[k] * s2;
    }
    double ml = lum3(m), S = 0;
    for (size_t k = 0; k < nk; k++) {
        double d = (lum3(in->rho + 3 * (size_t)kept[k]) - ml) / ml;
        S += w[k] * d * d;
    }
    double tau2 = nk > 1 && sw2 < 1 ? fmax(0, S - N) / (1 - sw2) : 0, si2 = noise2(in, i);
    double B = nk > 1 && si2 + tau2 > 0 ? si2 / (si2 + tau2) : 0;
    /* c_j = B w_j + (1 - B) [j = i]; kept[0] is i */
    double rad2 = 0, mc = 0, c2 = 0;
    for (size_t k = 0; k < nk; k++) {
        double c = B * w[k] + (k == 0 ? 1 - B : 0);
        rad2 += c * c * in->s_rad[kept[k]] * in->s_rad[kept[k]];
        mc += c * in->s_mc[kept[k]];
        c2 += c * c;
    }
    for (int ch = 0; ch < 3; ch++) out->rho[3 * i + ch] = (1 - B) * in->rho[3 * i + ch] + B * m[ch];
    out->s_rad[i] = sqrt(rad2);
    out->s_mc[i] = mc;
    out->s_bias[i] = B * sqrt(tau2 * fmax(0, 1 - 2 * w[0] + sw2));
    out->neff[i] = c2 > 0 ? 1 / c2 : 1;
    st.shrink = B;
    return st;
}

int rs_albpool_run(const rs_mesh *mesh, const rs_albpool_in *in, rs_albpool_out *out)
{
    size_t nf = in->nf;
    /* R of a kilometre: the distance then only orders the candidates (on a flat plane the normal
     * term is 0 for all, and the 64 kept are the nearest), at a weight change below 1e-3. */
    double *inv = malloc((nf ? nf : 1) * sizeof *inv);
    if (!inv) return -1;
    for (size_t f = 0; f < (nf ? nf : 1); f++) inv[f] = 1e-3;
    rs_pool p;
    int rc = rs_pool_build(mesh, inv, in->usable, in->usable, RS_ALBPOOL_PLANE, &p);
    free(inv);
    if (rc != 0) return -1;
    /* Per facet: its kept share and shrink (NaN when it is not pooled), summed afterwards in
     * facet order so that the summary does not depend on the threads. */
    double *st2 = malloc((nf ? 2 * nf : 1) * sizeof *st2);
    if (!st2) {
        rs_pool_free(&p);
        return -1;
    }
    int failed = 0;
#pragma omp parallel reduction(|| : failed)
    {
        uint32_t *kept = malloc(RS_POOL_MAX_NEIGHBOURS * sizeof *kept);
        double *w = malloc(RS_POOL_MAX_NEIGHBOURS * sizeof *w);
        if (!kept || !w) failed = 1;
#pragma omp for schedule(dynamic, 256)
        for (size_t i = 0; i < nf; i++) {
            memcpy(out->rho + 3 * i, in->rho + 3 * i, 3 * sizeof *out->rho);
            out->s_rad[i] = in->s_rad[i], out->s_mc[i] = in->s_mc[i], out->s_bias[i] = 0, out->neff[i] = 1;
            st2[2 * i] = st2[2 * i + 1] = NAN;
            /* a facet whose noise is unknown (not finite) keeps its own albedo, and no neighbour takes it
             * (agrees() fails on NaN) */
            if (!kept || !w || !in->usable[i] || !isfinite(noise2(in, i))) continue;
            facet_stats st = pool_facet(&p, in, i, kept, w, out);
            st2[2 * i] = st.kept_share, st2[2 * i + 1] = st.shrink;
        }
        free(kept);
        free(w);
    }
    rs_pool_free(&p);
    size_t pooled = 0, usable = 0;
    double neff = 0, kept_share = 0, shrink = 0;
    for (size_t i = 0; i < nf && !failed; i++) {
        if (isnan(st2[2 * i])) continue;
        usable++;
        pooled += out->neff[i] > 1.0001;
        neff += out->neff[i], kept_share += st2[2 * i], shrink += st2[2 * i + 1];
    }
    free(st2);
    if (failed) return -1;
    out->pooled = pooled;
    out->mean_neff = usable ? neff / usable : 1;
    out->mean_kept_share = usable ? kept_share / usable : 1;
    out->mean_shrink = usable ? shrink / usable : 0;
    return 0;
}

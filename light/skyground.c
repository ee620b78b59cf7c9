/* skyground: the ground's albedo from the model's lowest upward facets (skyground.h). */
#include "light/skyground.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/select.h"

/* The k/n quantile of v[0..n) (reordered). */
static double quantile(float *v, size_t n, double q)
{
    size_t k = (size_t)(q * (double)(n - 1) + 0.5);
    return rs_select_kth(v, n, k < n ? k : n - 1);
}

int rs_skyground_albedo(const rs_gather_ctx *g, const rs_mesh *mesh, const double *radiance, const uint8_t *observed,
                        rs_skyground *out, rs_err *err)
{
    memset(out, 0, sizeof *out);
    size_t nf = mesh->nfaces, nup = 0;
    uint32_t *up = malloc((nf ? nf : 1) * sizeof *up);
    float *z = malloc((nf ? nf : 1) * sizeof *z);
    if (!up || !z) {
        free(up);
        free(z);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory estimating the ground's albedo");
    }
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(mesh, f, &c, &n, &a);
        if (!observed[f] || !(a > 0) || !(n.z > RS_SKYGROUND_UP_Z)) continue;
        up[nup] = (uint32_t)f;
        z[nup++] = (float)c.z;
    }
    int rc = 0;
    if (nup < RS_SKYGROUND_MIN_FACETS) goto done;
    /* The 2nd percentile, not the lowest: a stray facet under the ground must not set the level. */
    out->level_z = quantile(z, nup, 0.02);
    size_t nlev = 0;
    for (size_t k = 0; k < nup; k++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(mesh, up[k], &c, &n, &a);
        if (c.z <= out->level_z + RS_SKYGROUND_LEVEL_M) up[nlev++] = up[k];
    }
    out->candidates = nlev;
    if (nlev < RS_SKYGROUND_MIN_FACETS) goto done;
    size_t stride = (nlev + RS_SKYGROUND_MAX_FACETS - 1) / RS_SKYGROUND_MAX_FACETS, m = 0;
    for (size_t k = 0; k < nlev; k += stride) up[m++] = up[k];
    rs_facet_gather *fg = calloc(m, sizeof *fg);
    float *rho = malloc(3 * m * sizeof *rho);
    if (!fg || !rho) {
        rc = rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory estimating the ground's albedo");
        goto free_gather;
    }
    if (rs_gather_list(g, up, m, fg, err) != 0) {
        rc = -1;
        goto free_gather;
    }
    size_t used = 0;
    for (size_t k = 0; k < m; k++) {
        /* Light from facets no camera saw is the reflectance stage's to estimate: a facet that
         * sees much of them would have its E short and its albedo high (by 7 % on the bench's
         * city, where the camera sees a tenth of the buildings). */
        double unseen = 0;
        for (uint32_t q = 0; q < fg[k].nentries; q++)
            if (!observed[fg[k].entries[q].col]) unseen += fg[k].entries[q].k;
        if (unseen > RS_SKYGROUND_MAX_UNSEEN * M_PI) {
            out->sees_unobserved++;
            continue;
        }
        double e[3];
        rs_gather_inter_observed(&fg[k], radiance, observed, e);
        int ok = 1;
        for (int ch = 0; ch < 3; ch++) {
            e[ch] += fg[k].esky[ch];
            ok &= e[ch] > 0 && isfinite(radiance[3 * (size_t)up[k] + ch]);
        }
        if (!ok) continue;
        for (int ch = 0; ch < 3; ch++) rho[ch * m + used] = (float)(M_PI * radiance[3 * (size_t)up[k] + ch] / e[ch]);
        used++;
    }
    if (used >= RS_SKYGROUND_MIN_FACETS) {
        out->facets = used;
        for (int ch = 0; ch < 3; ch++) {
            float *v = rho + ch * m;
            double lo = quantile(v, used, 0.16), hi = quantile(v, used, 0.84);
            out->albedo[ch] = quantile(v, used, 0.5);
            out->spread[ch] = 0.5 * (hi - lo);
        }
    }
free_gather:
    for (size_t k = 0; fg && k < m; k++) free(fg[k].entries);
    free(fg);
    free(rho);
done:
    free(up);
    free(z);
    return rc;
}

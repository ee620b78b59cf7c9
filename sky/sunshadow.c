/* sunshadow: a hidden sun's direct normal irradiance from its shadows (see sunshadow.h). */
#include "sky/sunshadow.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/select.h"

enum { DARK, LIT, MIXED }; /* full shadow, full sun, anything else (partial, unknown, facing away) */

#define MAX_PARTNERS 4096 /* per lit facet: enough for a median, bounded scratch */

static double luminance(const double *rgb)
{
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2];
}

/* Facet centroids sorted by the cell of a uniform grid (cell = radius): a radius query reads
 * the 27 cells around a point. */
typedef struct cell_index {
    double cell;
    uint64_t *key;   /* sorted */
    uint32_t *facet; /* in key order */
    size_t n;
} cell_index;

/* floor(v / cell) as an integer, clamped so that the cast is defined whatever the input. */
static int64_t cell_coord(double v, double cell)
{
    double q = floor(v / cell);
    if (isnan(q)) return 0;
    return q > 1e15 ? (int64_t)1e15 : q < -1e15 ? -(int64_t)1e15 : (int64_t)q;
}

static uint64_t cell_key(const cell_index *g, rs_v3 p, int dx, int dy, int dz)
{
    int64_t x = cell_coord(p.x, g->cell) + dx, y = cell_coord(p.y, g->cell) + dy, z = cell_coord(p.z, g->cell) + dz;
    const int64_t bias = (int64_t)1 << 20, mask = ((int64_t)1 << 21) - 1;
    return (uint64_t)((x + bias) & mask) << 42 | (uint64_t)((y + bias) & mask) << 21 | (uint64_t)((z + bias) & mask);
}

typedef struct key_facet {
    uint64_t key;
    uint32_t facet;
} key_facet;

static int cmp_key(const void *a, const void *b)
{
    const key_facet *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return (x->facet > y->facet) - (x->facet < y->facet);
}

static int index_build(cell_index *g, const rs_v3 *cen, size_t nf, double cell)
{
    key_facet *kf = malloc((nf ? nf : 1) * sizeof *kf);
    g->cell = cell;
    g->n = nf;
    g->key = malloc((nf ? nf : 1) * sizeof *g->key);
    g->facet = malloc((nf ? nf : 1) * sizeof *g->facet);
    if (!kf || !g->key || !g->facet) {
        free(kf);
        return -1;
    }
    for (size_t f = 0; f < nf; f++) kf[f] = (key_facet){cell_key(g, cen[f], 0, 0, 0), (uint32_t)f};
    qsort(kf, nf, sizeof *kf, cmp_key);
    for (size_t i = 0; i < nf; i++) {
        g->key[i] = kf[i].key;
        g->facet[i] = kf[i].facet;
    }
    free(kf);
    return 0;
}

/* [*lo, *hi) of the facets in cell key k. */
static void index_range(const cell_index *g, uint64_t k, size_t *lo, size_t *hi)
{
    size_t a = 0, b = g->n;
    while (a < b) {
        size_t m = a + (b - a) / 2;
        if (g->key[m] < k)
            a = m + 1;
        else
            b = m;
    }
    *lo = a;
    b = g->n;
    while (a < b) {
        size_t m = a + (b - a) / 2;
        if (g->key[m] <= k)
            a = m + 1;
        else
            b = m;
    }
    *hi = a;
}

/* Whether a facet of a state other than `state` lies within r of facet f. */
static int near_other(const cell_index *g, const rs_v3 *cen, const uint8_t *st, size_t f, double r)
{
    for (int dx = -1; dx <= 1; dx++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dz = -1; dz <= 1; dz++) {
                size_t lo, hi;
                index_range(g, cell_key(g, cen[f], dx, dy, dz), &lo, &hi);
                for (size_t q = lo; q < hi; q++) {
                    uint32_t j = g->facet[q];
                    if (st[j] != st[f] && rs_v3_len(rs_v3_sub(cen[j], cen[f])) < r) return 1;
                }
            }
    return 0;
}

double rs_sunshadow_margin(const rs_mesh *mesh, const uint8_t *observed, rs_v3 cam, int pano_height)
{
    size_t nf = mesh->nfaces, n = 0;
    float *v = malloc((nf ? nf : 1) * sizeof *v);
    if (!v) return 0;
    for (size_t f = 0; f < nf; f++) {
        if (!observed[f]) continue;
        rs_v3 p[3], c = {0, 0, 0};
        for (int k = 0; k < 3; k++) {
            p[k] = rs_mesh_vert(mesh, mesh->tris[3 * f + k]);
            c = rs_v3_add(c, rs_v3_scale(p[k], 1.0 / 3));
        }
        double edge = fmax(rs_v3_len(rs_v3_sub(p[1], p[0])),
                           fmax(rs_v3_len(rs_v3_sub(p[2], p[1])), rs_v3_len(rs_v3_sub(p[0], p[2]))));
        v[n++] = (float)(4 * rs_v3_len(rs_v3_sub(c, cam)) * M_PI / pano_height + 2 * edge);
    }
    double m = n ? rs_select_kth(v, n, n / 2) : 0;
    free(v);
    return m;
}

/* Per channel D of lit facet i from every shadowed partner within the radius on its plane,
 * medians into d[0..3); d[3] the median of what E's uncertainty (E_sigma) makes of the
 * luminance of D, hypot(Y_i / Y_j sigma_j, sigma_i) / cos_i. Returns the partner count. */
static size_t lit_facet_dni(const rs_sunshadow_input *in, const cell_index *g, const rs_v3 *cen, const rs_v3 *nrm,
                            const uint8_t *st, size_t i, float *scratch, double d[4])
{
    double cosi = rs_v3_dot(nrm[i], in->sun_dir);
    const double *Li = in->L + 3 * i, *Ei = in->E + 3 * i;
    size_t m = 0;
    for (int dx = -1; dx <= 1; dx++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dz = -1; dz <= 1; dz++) {
                size_t lo, hi;
                index_range(g, cell_key(g, cen[i], dx, dy, dz), &lo, &hi);
                for (size_t q = lo; q < hi && m < MAX_PARTNERS; q++) {
                    uint32_t j = g->facet[q];
                    if (st[j] != DARK) continue;
                    rs_v3 off = rs_v3_sub(cen[j], cen[i]);
                    if (rs_v3_len(off) > in->radius || rs_v3_dot(nrm[i], nrm[j]) < 0.996 ||
                        fabs(rs_v3_dot(nrm[i], off)) > 0.1 * in->radius)
                        continue; /* not on i's plane (5 degrees, a tenth of the radius) */
                    const double *Lj = in->L + 3 * (size_t)j, *Ej = in->E + 3 * (size_t)j;
                    double d[4], ratio = luminance(Li) / luminance(Lj);
                    for (int ch = 0; ch < 3; ch++) d[ch] = (Li[ch] * Ej[ch] / Lj[ch] - Ei[ch]) / cosi;
                    d[3] = in->E_sigma ? hypot(ratio * in->E_sigma[j], in->E_sigma[i]) / cosi : 0;
                    if (!(isfinite(d[0]) && isfinite(d[1]) && isfinite(d[2]) && isfinite(d[3]))) continue;
                    for (int ch = 0; ch < 4; ch++) scratch[ch * MAX_PARTNERS + m] = (float)d[ch];
                    m++;
                }
            }
    for (int ch = 0; ch < 4 && m; ch++) d[ch] = rs_select_kth(scratch + ch * MAX_PARTNERS, m, m / 2);
    return m;
}

/* Median absolute deviation of v[0..n) about med (v is reordered). */
static double mad(float *v, size_t n, double med)
{
    for (size_t i = 0; i < n; i++) v[i] = (float)fabs(v[i] - med);
    return n ? rs_select_kth(v, n, n / 2) : 0;
}

/* Each facet's centroid, normal and state toward the sun: LIT or DARK when it faces the sun and
 * sees at least RS_SUNSHADOW_FULL of its disc or at most 1 - that, MIXED otherwise. */
static void classify_facets(const rs_sunshadow_input *in, rs_v3 *cen, rs_v3 *nrm, uint8_t *st)
{
    for (size_t f = 0; f < in->mesh->nfaces; f++) {
        double a;
        rs_mesh_face(in->mesh, f, &cen[f], &nrm[f], &a);
        double cosn = rs_v3_dot(nrm[f], in->sun_dir), v = in->vis[f];
        st[f] = MIXED;
        if (!(a > 0) || !(cosn > 0.05) || !(v >= 0)) continue;
        st[f] = v >= RS_SUNSHADOW_FULL ? LIT : v <= 1 - RS_SUNSHADOW_FULL ? DARK : MIXED;
    }
}

/* Candidates: observed, positive radiance and irradiance in every channel, beyond the margin;
 * every other facet becomes MIXED. Counts the shadowed candidates (out->shadowed) and lists the
 * lit ones not grazed by the sun in lit[0 .. *nlit). -1: out of memory. */
static int select_candidates(const rs_sunshadow_input *in, const cell_index *g, const rs_v3 *cen, const rs_v3 *nrm,
                             uint8_t *st, uint32_t *lit, size_t *nlit, rs_sunshadow *out)
{
    size_t nf = in->mesh->nfaces, n = 0;
    uint8_t *cand = malloc(nf ? nf : 1);
    if (!cand) return -1;
#pragma omp parallel for schedule(dynamic, 256)
    for (size_t f = 0; f < nf; f++) {
        const double *L = in->L + 3 * f, *E = in->E + 3 * f;
        cand[f] = st[f] != MIXED && in->observed[f] && L[0] > 0 && L[1] > 0 && L[2] > 0 && E[0] > 0 && E[1] > 0 &&
            E[2] > 0 && !near_other(g, cen, st, f, in->margin);
    }
    for (size_t f = 0; f < nf; f++) {
        if (!cand[f]) {
            if (st[f] != MIXED) st[f] = MIXED; /* partners must be beyond the margin too */
            continue;
        }
        if (st[f] == DARK)
            out->shadowed++;
        else if (rs_v3_dot(nrm[f], in->sun_dir) > 0.1) /* grazing: D / cos_i amplifies noise */
            lit[n++] = (uint32_t)f;
    }
    free(cand);
    *nlit = n;
    return 0;
}

/* D of every listed lit facet that has a shadowed partner (lit_facet_dni), in parallel; then
 * those facets compacted to the front: lit[0 .. *nused) and their D and E's share in
 * dl[4 k .. 4 k + 3]. -1: out of memory. */
static int lit_facets_dni(const rs_sunshadow_input *in, const cell_index *g, const rs_v3 *cen, const rs_v3 *nrm,
                          const uint8_t *st, uint32_t *lit, size_t nlit, float *dl, size_t *nused)
{
    uint8_t *used = calloc(nlit ? nlit : 1, 1);
    int failed = !used;
#pragma omp parallel
    {
        float *scratch = malloc(4 * MAX_PARTNERS * sizeof *scratch);
        if (!scratch) {
#pragma omp atomic write
            failed = 1;
        }
#pragma omp for schedule(dynamic, 64)
        for (size_t k = 0; k < nlit; k++) {
            double d[4];
            if (!scratch || !used) continue;
            if (lit_facet_dni(in, g, cen, nrm, st, lit[k], scratch, d) == 0) continue;
            used[k] = 1;
            for (int ch = 0; ch < 4; ch++) dl[4 * k + ch] = (float)d[ch];
        }
        free(scratch);
    }
    if (failed) {
        free(used);
        return -1;
    }
    size_t nu = 0;
    for (size_t k = 0; k < nlit; k++)
        if (used[k]) {
            memmove(dl + 4 * nu, dl + 4 * k, 4 * sizeof *dl);
            lit[nu++] = lit[k];
        }
    free(used);
    *nused = nu;
    return 0;
}

void rs_sunshadow_upper_cluster(const float *v, size_t n, size_t min_count, float *scratch, rs_sunshadow_cluster *out)
{
    memset(out, 0, sizeof *out);
    out->n = n;
    float *pos = scratch, *work = scratch + n;
    size_t k = 0;
    for (size_t i = 0; i < n; i++)
        if (v[i] <= 0) work[k++] = -v[i];
    double s0 = k ? 1.4826 * rs_select_kth(work, k, k / 2) : 0, t = 3 * s0;
    size_t np = 0;
    for (size_t i = 0; i < n; i++) {
        if (v[i] > t) pos[np++] = v[i];
        out->negative_tail += v[i] < -t;
    }
    out->null_noise = s0;
    out->positive = np;
    if (np == 0 || np < min_count || np <= 3 * out->negative_tail) return;
    /* The mode of the positive values: the median within +- 2.5 MADs of the last one, iterated. */
    for (size_t i = 0; i < np; i++) work[i] = pos[i];
    double m = rs_select_kth(work, np, np / 2), s = 0;
    for (size_t i = 0; i < np; i++) work[i] = (float)fabs(pos[i] - m);
    s = 1.4826 * rs_select_kth(work, np, np / 2);
    for (int it = 0; it < 20 && s > 0; it++) {
        size_t w = 0;
        for (size_t i = 0; i < np; i++)
            if (fabs(pos[i] - m) <= 2.5 * s) work[w++] = pos[i];
        if (w < min_count || w == 0) break;
        double m2 = rs_select_kth(work, w, w / 2);
        for (size_t i = 0, j = 0; i < np; i++)
            if (fabs(pos[i] - m) <= 2.5 * s) work[j++] = (float)fabs(pos[i] - m2);
        double s2 = 1.4826 * rs_select_kth(work, w, w / 2);
        int done = fabs(m2 - m) <= 1e-6 * fabs(m2) + 1e-12;
        m = m2;
        if (s2 > 0) s = s2;
        if (done) break;
    }
    /* The consensus: every value within 3 of those MADs of the mode (below 3 s0 too). */
    size_t c = 0;
    for (size_t i = 0; i < n; i++)
        if (fabs(v[i] - m) <= 3 * s) work[c++] = v[i];
    if (c == 0 || c < min_count) return;
    out->location = rs_select_kth(work, c, c / 2);
    for (size_t i = 0, j = 0; i < n; i++)
        if (fabs(v[i] - m) <= 3 * s) work[j++] = (float)fabs(v[i] - out->location);
    out->spread = 1.4826 * rs_select_kth(work, c, c / 2);
    out->consensus = c;
    out->valid = 1;
}

/* Which of the nu paired lit facets give the DNI (dl as lit_facets_dni leaves them): all of
 * them, whose median per channel it was before; or, when the median lies outside the sun's
 * cluster by more than half its spread (leaks outvote the real pairs), the cluster's consensus.
 * Those facets are compacted to the front of lit and dl; returns their count. */
static size_t consensus_facets(const rs_sunshadow_input *in, uint32_t *lit, float *dl, size_t nu, float *col,
                               float *scratch, rs_sunshadow *out)
{
    for (size_t k = 0; k < nu; k++) {
        double d[3] = {dl[4 * k], dl[4 * k + 1], dl[4 * k + 2]};
        col[k] = (float)luminance(d);
        scratch[k] = col[k];
    }
    out->median_lum = rs_select_kth(scratch, nu, nu / 2);
    out->consensus = nu;
    if (in->median_only) return nu;
    rs_sunshadow_cluster cl;
    rs_sunshadow_upper_cluster(col, nu, RS_SUNSHADOW_MIN_LIT, scratch, &cl);
    if (!cl.valid || !(fabs(out->median_lum - cl.location) > 0.5 * cl.spread)) return nu;
    size_t c = 0;
    for (size_t k = 0; k < nu; k++) {
        if (!(fabs(col[k] - cl.location) <= 3 * cl.spread)) continue;
        memmove(dl + 4 * c, dl + 4 * k, 4 * sizeof *dl);
        lit[c++] = lit[k];
    }
    out->upper_cluster = 1;
    out->consensus = c;
    return c;
}

/* The estimate from the nu used lit facets (lit, dl as lit_facets_dni leaves them): the median
 * D per channel over the consensus (consensus_facets), its standard error between blocks, and
 * what E's uncertainty makes of it. -1: out of memory. */
static int dni_statistics(const rs_sunshadow_input *in, const rs_v3 *cen, uint32_t *lit, float *dl, size_t nu,
                          rs_sunshadow *out)
{
    float *col = malloc(nu * sizeof *col), *blk = malloc(2 * nu * sizeof *blk), *tmp = malloc(nu * sizeof *tmp);
    key_facet *bk = malloc(nu * sizeof *bk);
    if (!col || !blk || !tmp || !bk) {
        free(col);
        free(blk);
        free(tmp);
        free(bk);
        return -1;
    }
    nu = consensus_facets(in, lit, dl, nu, col, blk, out);
    for (int ch = 0; ch < 3; ch++) {
        for (size_t k = 0; k < nu; k++) col[k] = dl[4 * k + ch];
        out->dni[ch] = fmax(0, rs_select_kth(col, nu, nu / 2));
    }
    out->dni_lum = luminance(out->dni);
    /* Its standard error: lit facets close together share partners and pixels, so the spread
     * is measured between blocks of 2 x radius (their medians); the median's standard error is
     * 1.2533 x 1.4826 MAD / sqrt(blocks). With fewer than 3 blocks, the spread over facets. */
    cell_index bg = {.cell = 2 * in->radius};
    for (size_t k = 0; k < nu; k++) {
        double d[3] = {dl[4 * k], dl[4 * k + 1], dl[4 * k + 2]};
        bk[k] = (key_facet){cell_key(&bg, cen[lit[k]], 0, 0, 0), (uint32_t)k};
        col[k] = (float)luminance(d);
    }
    qsort(bk, nu, sizeof *bk, cmp_key);
    size_t nb = 0;
    for (size_t a = 0, b; a < nu; a = b) {
        size_t n = 0;
        for (b = a; b < nu && bk[b].key == bk[a].key; b++) tmp[n++] = col[bk[b].facet];
        blk[nb++] = rs_select_kth(tmp, n, n / 2);
    }
    out->blocks = nb;
    out->sigma_stat_lum =
        nb >= 3 ? 1.2533 * 1.4826 * mad(blk, nb, out->dni_lum) / sqrt((double)nb) : 1.4826 * mad(col, nu, out->dni_lum);
    /* What the uncertainty of E (the sky fill's) makes of it: the same for every pair, not
     * averaged away; the median over lit facets. */
    for (size_t k = 0; k < nu; k++) col[k] = dl[4 * k + 3];
    out->sigma_sys_lum = rs_select_kth(col, nu, nu / 2);
    out->sigma_lum = hypot(out->sigma_stat_lum, out->sigma_sys_lum);
    free(col);
    free(blk);
    free(tmp);
    free(bk);
    return 0;
}

/* Albedo above 1 without the sun on the lit candidates lit[0..nlit): each such facet needs at
 * least (pi L - E) / cos_i of DNI per channel (its albedo is at most 1). Counts them and sets
 * the floor (their median need per channel, and its luminance) when there are at least
 * RS_SUNSHADOW_MIN_LIT. -1: out of memory. */
static int albedo_floor(const rs_sunshadow_input *in, const rs_v3 *nrm, const uint32_t *lit, size_t nlit,
                        double floor_rgb[3], rs_sunshadow *out)
{
    float *need = malloc((4 * nlit + 1) * sizeof *need);
    if (!need) return -1;
    size_t n = 0;
    for (size_t k = 0; k < nlit; k++) {
        uint32_t f = lit[k];
        const double *L = in->L + 3 * (size_t)f, *E = in->E + 3 * (size_t)f;
        double cosi = rs_v3_dot(nrm[f], in->sun_dir), yl = luminance(L), ye = luminance(E);
        if (!(M_PI * yl > RS_SUNSHADOW_ABOVE_ONE * ye)) continue;
        for (int ch = 0; ch < 3; ch++) need[ch * nlit + n] = (float)((M_PI * L[ch] - E[ch]) / cosi);
        need[3 * nlit + n] = (float)((M_PI * yl - ye) / cosi);
        n++;
    }
    out->above_one = n;
    if (n >= RS_SUNSHADOW_MIN_LIT) {
        for (int ch = 0; ch < 3; ch++) floor_rgb[ch] = fmax(0, rs_select_kth(need + ch * nlit, n, n / 2));
        out->floor_lum = rs_select_kth(need + 3 * nlit, n, n / 2);
    }
    free(need);
    return 0;
}

int rs_sunshadow_estimate(const rs_sunshadow_input *in, rs_sunshadow *out, rs_err *err)
{
    memset(out, 0, sizeof *out);
    if (!(in->radius > 0) || !(in->margin >= 0)) return 1; /* nothing observed to size them */
    size_t nf = in->mesh->nfaces, nlit = 0, nused = 0;
    rs_v3 *cen = malloc((nf ? nf : 1) * sizeof *cen), *nrm = malloc((nf ? nf : 1) * sizeof *nrm);
    uint8_t *st = malloc(nf ? nf : 1);
    uint32_t *lit = malloc((nf ? nf : 1) * sizeof *lit);
    float *dl = malloc((4 * nf + 1) * sizeof *dl); /* per used lit facet: D per channel, E's share */
    cell_index g = {0};
    int rc = -1;
    if (!cen || !nrm || !st || !lit || !dl) goto out;
    classify_facets(in, cen, nrm, st);
    if (index_build(&g, cen, nf, in->radius) != 0 || select_candidates(in, &g, cen, nrm, st, lit, &nlit, out) != 0)
        goto out;
    out->lit = nlit;
    double floor_rgb[3] = {0, 0, 0};
    if (!in->median_only && albedo_floor(in, nrm, lit, nlit, floor_rgb, out) != 0) goto out;
    if (lit_facets_dni(in, &g, cen, nrm, st, lit, nlit, dl, &nused) != 0) goto out;
    out->lit_used = nused;
    rc = nused < RS_SUNSHADOW_MIN_LIT ? 1 : dni_statistics(in, cen, lit, dl, nused, out);
    if (rc == 0 && out->floor_lum > out->dni_lum) { /* the pairs say less than the albedo allows */
        for (int ch = 0; ch < 3; ch++) out->dni[ch] = floor_rgb[ch];
        out->dni_lum = luminance(out->dni);
        out->floored = 1;
    }
out:
    free(g.key);
    free(g.facet);
    free(cen);
    free(nrm);
    free(st);
    free(lit);
    free(dl);
    if (rc < 0) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory estimating the sun from the shadows");
    return rc;
}

int rs_sunshadow_pairs_build(const rs_mesh *mesh, const uint8_t *observed, double margin, double radius,
                             int max_per_facet, rs_sunshadow_pairs *out, rs_err *err)
{
    memset(out, 0, sizeof *out);
    if (!(radius > 0)) return 0; /* nothing observed: no pairs */
    size_t nf = mesh->nfaces, cap = nf * (size_t)max_per_facet;
    rs_v3 *cen = calloc(nf ? nf : 1, sizeof *cen), *nrm = calloc(nf ? nf : 1, sizeof *nrm);
    uint32_t *cnt = calloc(nf ? nf : 1, sizeof *cnt);
    out->a = malloc((cap ? cap : 1) * sizeof *out->a);
    out->b = malloc((cap ? cap : 1) * sizeof *out->b);
    cell_index g = {0};
    int rc = -1;
    if (!cen || !nrm || !cnt || !out->a || !out->b) goto done;
    for (size_t f = 0; f < nf; f++) {
        double area;
        rs_mesh_face(mesh, f, &cen[f], &nrm[f], &area);
    }
    if (index_build(&g, cen, nf, radius) != 0) goto done;
    /* Serial: each pair is taken once (i < j) and both ends count toward their cap. */
    for (size_t i = 0; i < nf; i++) {
        if (!observed[i] || rs_v3_len(nrm[i]) == 0) continue;
        for (int dx = -1; dx <= 1 && cnt[i] < (uint32_t)max_per_facet; dx++)
            for (int dy = -1; dy <= 1 && cnt[i] < (uint32_t)max_per_facet; dy++)
                for (int dz = -1; dz <= 1 && cnt[i] < (uint32_t)max_per_facet; dz++) {
                    size_t lo, hi;
                    index_range(&g, cell_key(&g, cen[i], dx, dy, dz), &lo, &hi);
                    for (size_t q = lo; q < hi && cnt[i] < (uint32_t)max_per_facet; q++) {
                        uint32_t j = g.facet[q];
                        if (j <= i || !observed[j] || cnt[j] >= (uint32_t)max_per_facet) continue;
                        rs_v3 off = rs_v3_sub(cen[j], cen[i]);
                        double d = rs_v3_len(off);
                        if (d < margin || d > radius || rs_v3_dot(nrm[i], nrm[j]) < 0.996 ||
                            fabs(rs_v3_dot(nrm[i], off)) > 0.1 * radius)
                            continue;
                        out->a[out->n] = (uint32_t)i;
                        out->b[out->n++] = j;
                        cnt[i]++;
                        cnt[j]++;
                    }
                }
    }
    rc = 0;
done:
    free(g.key);
    free(g.facet);
    free(cen);
    free(nrm);
    free(cnt);
    if (rc == 0) return 0;
    rs_sunshadow_pairs_free(out);
    return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory pairing the facets for the sun search");
}

void rs_sunshadow_pairs_free(rs_sunshadow_pairs *p)
{
    free(p->a);
    free(p->b);
    memset(p, 0, sizeof *p);
}

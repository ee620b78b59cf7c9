/* sunsearch: a hidden sun's direction from the shadows on the model (see sunsearch.h). */
#include "sky/sunsearch.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/select.h"

#define DEG (M_PI / 180)

enum { NONE, LIT, DARK };

typedef struct search_ctx {
    const rs_scene *scene;
    const rs_skyenv *env;
    const rs_sunshadow_pairs *pairs;
    uint32_t *facets; /* the facets of the pairs, once each */
    uint32_t *slot;   /* nf: facet -> index in facets */
    size_t nfacets;
    rs_v3 *org, *nrm; /* per entry of facets: ray origin (offset centroid), normal */
    float *log_ratio; /* nf: log(Y / E), NAN where either is not positive */
} search_ctx;

/* Whether direction s is one the map filled, above the horizon. */
static int hidden(const rs_skyenv *env, rs_v3 s)
{
    if (!(s.z > 0.02)) return 0;
    int c, r;
    rs_pano_world_to_pixel(&env->pose, env->width, env->height, s, &c, &r);
    return env->filled[(size_t)r * env->width + c];
}

/* Scores of direction s: the median contrast over lit-shadowed pairs (-INFINITY with too few),
 * and with tau > 0 the edge score: sum over lit-shadowed pairs of c - tau (a predicted edge
 * that is real gains, one that is not loses tau) less the sum over pairs both lit or both
 * shadowed of max(0, |c| - tau) (a real edge the direction does not predict). The median alone
 * is flat along a ridge of directions that put the long shadow lines in the same place; the
 * edge score also counts the short edges (building ends, steps) that tell them apart.
 * Per-thread scratch: rays, occl, state (nfacets each), contrast (pairs->n). */
static double score(const search_ctx *c, rs_v3 s, double tau, rs_ray *rays, uint8_t *occl, uint8_t *state,
                    float *contrast, size_t *npairs, double *edge)
{
    size_t nr = 0;
    for (size_t k = 0; k < c->nfacets; k++) {
        state[k] = NONE;
        if (!(rs_v3_dot(c->nrm[k], s) > 0.1)) continue;
        rays[nr] = (rs_ray){.org = c->org[k], .dir = s, .tnear = 0, .tfar = INFINITY};
        state[k] = LIT; /* until the ray says otherwise */
        nr++;
    }
    rs_scene_occluded(c->scene, rays, occl, nr);
    for (size_t k = 0, r = 0; k < c->nfacets; k++)
        if (state[k] == LIT && occl[r++]) state[k] = DARK;
    size_t m = 0;
    double e = 0;
    for (size_t p = 0; p < c->pairs->n; p++) {
        uint32_t a = c->pairs->a[p], b = c->pairs->b[p];
        uint8_t sa = state[c->slot[a]], sb = state[c->slot[b]];
        if (sa == NONE || sb == NONE) continue;
        float d = sa == LIT ? c->log_ratio[a] - c->log_ratio[b] : c->log_ratio[b] - c->log_ratio[a];
        if (!isfinite(d)) continue;
        if (sa == sb) {
            e -= fmax(0, fabs(d) - tau);
            continue;
        }
        e += d - tau;
        contrast[m++] = d;
    }
    *npairs = m;
    *edge = e;
    return m >= RS_SUNSEARCH_MIN_PAIRS ? rs_select_kth(contrast, m, m / 2) : -INFINITY;
}

/* Scores dirs[0..n) on all threads: the median contrast into med and, with tau > 0, the edge
 * score into edge (-INFINITY where the median is); np the pairs. -1 out of memory. */
static int score_all(const search_ctx *c, const rs_v3 *dirs, int n, double tau, double *med, double *edge, size_t *np)
{
    int failed = 0;
#pragma omp parallel
    {
        rs_ray *rays = malloc((c->nfacets + 1) * sizeof *rays);
        uint8_t *occl = malloc(c->nfacets + 1), *state = malloc(c->nfacets + 1);
        float *contrast = malloc((c->pairs->n + 1) * sizeof *contrast);
        if (!rays || !occl || !state || !contrast) {
#pragma omp atomic write
            failed = 1;
        }
#pragma omp for schedule(dynamic, 1)
        for (int i = 0; i < n; i++) {
            if (!rays || !occl || !state || !contrast) continue;
            med[i] = score(c, dirs[i], tau, rays, occl, state, contrast, &np[i], &edge[i]);
            if (!isfinite(med[i])) edge[i] = -INFINITY;
        }
        free(rays);
        free(occl);
        free(state);
        free(contrast);
    }
    return failed ? -1 : 0;
}

/* Directions on a grid of `step` around `centre` within `half` (in a tangent frame), hidden ones
 * only, into dirs (room for (2 half / step + 1)^2); returns their count. */
static int local_grid(const rs_skyenv *env, rs_v3 centre, double half, double step, rs_v3 *dirs)
{
    rs_v3 t, b;
    rs_v3_basis(centre, &t, &b);
    int n = 0, k = (int)floor(half / step + 1e-9);
    for (int i = -k; i <= k; i++)
        for (int j = -k; j <= k; j++) {
            rs_v3 off = rs_v3_add(rs_v3_scale(t, tan(i * step)), rs_v3_scale(b, tan(j * step)));
            rs_v3 d = rs_v3_norm(rs_v3_add(centre, off));
            if (hidden(env, d)) dirs[n++] = d;
        }
    return n;
}

/* The index of the best score in sc[0..n) that is not within `apart` of the directions in
 * taken[0..nt); -1 when none is finite. */
static int best_apart(const rs_v3 *dirs, const double *sc, int n, const rs_v3 *taken, int nt, double apart)
{
    int best = -1;
    for (int i = 0; i < n; i++) {
        if (!isfinite(sc[i]) || (best >= 0 && sc[i] <= sc[best])) continue;
        int close = 0;
        for (int k = 0; k < nt; k++) close |= rs_v3_dot(dirs[i], taken[k]) > cos(apart);
        if (!close) best = i;
    }
    return best;
}

int rs_sunsearch_run(const rs_scene *scene, const rs_skyenv *env, const rs_sunshadow_pairs *pairs, const double *E,
                     const double *L, const uint8_t *observed, rs_sunsearch *out, rs_err *err)
{
    memset(out, 0, sizeof *out);
    const rs_mesh *m = rs_scene_mesh(scene);
    size_t nf = m->nfaces;
    size_t stride = (pairs->n + RS_SUNSEARCH_MAX_PAIRS - 1) / RS_SUNSEARCH_MAX_PAIRS;
    rs_sunshadow_pairs sub = {.n = 0};
    if (stride > 1) { /* every stride-th pair: spread over the model */
        sub.a = malloc(RS_SUNSEARCH_MAX_PAIRS * sizeof *sub.a);
        sub.b = malloc(RS_SUNSEARCH_MAX_PAIRS * sizeof *sub.b);
        if (!sub.a || !sub.b) {
            rs_sunshadow_pairs_free(&sub);
            return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory searching the shadows for the sun");
        }
        for (size_t p = 0; p < pairs->n && sub.n < RS_SUNSEARCH_MAX_PAIRS; p += stride) {
            sub.a[sub.n] = pairs->a[p];
            sub.b[sub.n++] = pairs->b[p];
        }
        pairs = &sub;
    }
    search_ctx c = {.scene = scene, .env = env, .pairs = pairs};
    c.slot = malloc((nf ? nf : 1) * sizeof *c.slot);
    c.facets = malloc((nf ? nf : 1) * sizeof *c.facets);
    c.org = malloc((nf ? nf : 1) * sizeof *c.org);
    c.nrm = malloc((nf ? nf : 1) * sizeof *c.nrm);
    c.log_ratio = malloc((nf ? nf : 1) * sizeof *c.log_ratio);
    int cap = 4096, rc = -1;
    rs_v3 *dirs = malloc(cap * sizeof *dirs);
    double *med = malloc(cap * sizeof *med), *edge = malloc(cap * sizeof *edge);
    size_t *np = malloc(cap * sizeof *np);
    if (!c.slot || !c.facets || !c.org || !c.nrm || !c.log_ratio || !dirs || !med || !edge || !np) goto done;
    for (size_t f = 0; f < nf; f++) {
        c.slot[f] = UINT32_MAX;
        const double *e = E + 3 * f, *l = L + 3 * f;
        double y = 0.2126 * l[0] + 0.7152 * l[1] + 0.0722 * l[2], ye = 0.2126 * e[0] + 0.7152 * e[1] + 0.0722 * e[2];
        c.log_ratio[f] = observed[f] && y > 0 && ye > 0 ? (float)log(y / ye) : NAN;
    }
    for (size_t p = 0; p < 2 * pairs->n; p++) {
        uint32_t f = p < pairs->n ? pairs->a[p] : pairs->b[p - pairs->n];
        if (c.slot[f] != UINT32_MAX) continue;
        rs_v3 cen, n;
        double area;
        rs_mesh_face(m, f, &cen, &n, &area);
        c.slot[f] = (uint32_t)c.nfacets;
        c.org[c.nfacets] = rs_v3_add(cen, rs_v3_scale(n, rs_scene_offset(scene, cen)));
        c.nrm[c.nfacets] = n;
        c.facets[c.nfacets++] = f;
    }
    /* Coarse: 8 degrees apart in elevation and along each row, by the median contrast; its
     * best sets tau, half of it, and the same directions are scored again by edges. */
    int n = 0;
    for (double el = 4 * DEG; el < 88 * DEG && n < cap; el += 8 * DEG) {
        int naz = (int)fmax(1, round(360 * cos(el) / 8));
        for (int k = 0; k < naz && n < cap; k++) {
            double az = 2 * M_PI * k / naz;
            rs_v3 d = rs_v3_make(cos(el) * cos(az), cos(el) * sin(az), sin(el));
            if (hidden(env, d)) dirs[n++] = d;
        }
    }
    if (score_all(&c, dirs, n, 0, med, edge, np) != 0) goto done;
    out->candidates = n;
    int top = best_apart(dirs, med, n, NULL, 0, 0);
    if (top < 0) {
        rc = 1; /* no direction had enough pairs */
        goto done;
    }
    double tau = 0.5 * med[top];
    if (score_all(&c, dirs, n, tau, med, edge, np) != 0) goto done;
    out->candidates += n;
    /* The best three by edges, at least 8 degrees apart, each refined at 2 then 0.5 degrees. */
    rs_v3 seeds[3];
    int nseeds = 0;
    for (int k = 0; k < 3; k++) {
        int i = best_apart(dirs, edge, n, seeds, nseeds, 8 * DEG);
        if (i >= 0) seeds[nseeds++] = dirs[i];
    }
    double best = -INFINITY;
    for (int k = 0; k < nseeds; k++) {
        rs_v3 centre = seeds[k];
        for (int level = 0; level < 2; level++) {
            int nl = local_grid(env, centre, level ? 2 * DEG : 8 * DEG, level ? 0.5 * DEG : 2 * DEG, dirs);
            if (score_all(&c, dirs, nl, tau, med, edge, np) != 0) goto done;
            out->candidates += nl;
            int i = best_apart(dirs, edge, nl, NULL, 0, 0);
            if (i < 0) break;
            centre = dirs[i];
            if (edge[i] > best) {
                best = edge[i];
                out->dir = dirs[i];
                out->score = med[i];
                out->edge_score = edge[i];
                out->pairs = np[i];
            }
        }
    }
    rc = isfinite(best) ? 0 : 1;
done:
    free(c.slot);
    free(c.facets);
    free(c.org);
    free(c.nrm);
    free(c.log_ratio);
    rs_sunshadow_pairs_free(&sub);
    free(dirs);
    free(med);
    free(edge);
    free(np);
    if (rc < 0) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory searching the shadows for the sun");
    return rc;
}

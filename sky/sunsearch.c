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
    int upper;        /* score by the sun's cluster of contrasts */
    int forgive;      /* edge score: predicted edges not seen cost nothing; albedo above 1 counts */
} search_ctx;

/* Directions within cos_cone of a prior (the visible sky's sun), or anywhere (prior NULL). */
typedef struct cone {
    const rs_v3 *prior;
    double cos_cone;
} cone;

#define SPREAD_BLOCKS 32 /* blocks of consecutive pairs for the direction's bootstrap */
#define SPREAD_DRAWS  200

/* Whether direction s is one the map filled, above the horizon. */
static int hidden(const rs_skyenv *env, rs_v3 s)
{
    if (!(s.z > 0.02)) return 0;
    int c, r;
    rs_pano_world_to_pixel(&env->pose, env->width, env->height, s, &c, &r);
    return env->filled[(size_t)r * env->width + c];
}

/* Scores of direction s: the log contrast over lit-shadowed pairs (-INFINITY with too few): their
 * median, or with c->upper the location of their sun cluster (rs_sunshadow_upper_cluster: where
 * the model lets the sun through gaps it lacks, lit ends really in shadow give contrasts about 0
 * and can outnumber the real ones). With tau > 0 also the edge score: the sum over lit-shadowed
 * pairs of c - tau (a predicted edge that is real gains, one that is not loses tau; with
 * c->upper one the radiance does not show, |c| <= tau, costs nothing, as the model may lack its
 * occluder, and one it contradicts costs its excess) less the sum over pairs both lit or both
 * shadowed of max(0, |c| - tau) (a real edge the direction does not predict). With c->upper,
 * facets whose albedo without the sun is above RS_SUNSHADOW_ABOVE_ONE add their log excess when
 * the direction lights them and lose it when it shadows them: missing light. The median alone
 * is flat along a ridge of directions that put the long shadow lines in the same place; the
 * edge score also counts the short edges (building ends, steps) that tell them apart.
 * blocks (SPREAD_BLOCKS, or NULL): the edge score's sum per block of consecutive pairs.
 * Per-thread scratch: rays, occl, state (nfacets each), contrast (3 pairs->n). */
static double score(const search_ctx *c, rs_v3 s, double tau, rs_ray *rays, uint8_t *occl, uint8_t *state,
                    float *contrast, size_t *npairs, double *edge, double *blocks, double *median)
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
    double e = 0, excess_log = log(RS_SUNSHADOW_ABOVE_ONE / M_PI);
    for (size_t k = 0, r = 0; k < c->nfacets; k++) {
        if (state[k] == LIT && occl[r++]) state[k] = DARK;
        float x = c->log_ratio[c->facets[k]];
        if (c->forgive && tau > 0 && state[k] != NONE && x > excess_log)
            e += state[k] == LIT ? x - excess_log : -(x - excess_log);
    }
    if (blocks)
        for (int k = 0; k < SPREAD_BLOCKS; k++) blocks[k] = 0;
    size_t m = 0;
    for (size_t p = 0; p < c->pairs->n; p++) {
        uint32_t a = c->pairs->a[p], b = c->pairs->b[p];
        uint8_t sa = state[c->slot[a]], sb = state[c->slot[b]];
        if (sa == NONE || sb == NONE) continue;
        float d = sa == LIT ? c->log_ratio[a] - c->log_ratio[b] : c->log_ratio[b] - c->log_ratio[a];
        if (!isfinite(d)) continue;
        double g;
        if (sa == sb)
            g = -fmax(0, fabs(d) - tau);
        else {
            g = !c->forgive ? d - tau : d > tau ? d - tau : d < -tau ? d + tau : 0;
            contrast[m++] = d;
        }
        e += g;
        if (blocks) blocks[p * SPREAD_BLOCKS / c->pairs->n] += g;
    }
    *npairs = m;
    *edge = e;
    if (m < RS_SUNSEARCH_MIN_PAIRS) return *median = -INFINITY;
    for (size_t p = 0; p < m; p++) contrast[m + p] = contrast[p];
    *median = rs_select_kth(contrast + m, m, m / 2);
    if (!c->upper) return *median;
    rs_sunshadow_cluster cl;
    rs_sunshadow_upper_cluster(contrast, m, RS_SUNSEARCH_MIN_PAIRS, contrast + m, &cl);
    if (!cl.valid) return -INFINITY;
    *npairs = cl.consensus;
    return fmax(*median, cl.location);
}

/* Scores dirs[0..n) on all threads: the median contrast into med and, with tau > 0, the edge
 * score into edge (-INFINITY where the median is); np the pairs. -1 out of memory. */
static int score_all(const search_ctx *c, const rs_v3 *dirs, int n, double tau, double *med, double *edge, size_t *np,
                     double *median, double *blocks)
{
    int failed = 0;
#pragma omp parallel
    {
        rs_ray *rays = malloc((c->nfacets + 1) * sizeof *rays);
        uint8_t *occl = malloc(c->nfacets + 1), *state = malloc(c->nfacets + 1);
        float *contrast = malloc((3 * c->pairs->n + 1) * sizeof *contrast);
        if (!rays || !occl || !state || !contrast) {
#pragma omp atomic write
            failed = 1;
        }
#pragma omp for schedule(dynamic, 1)
        for (int i = 0; i < n; i++) {
            if (!rays || !occl || !state || !contrast) continue;
            double mi;
            med[i] = score(c, dirs[i], tau, rays, occl, state, contrast, &np[i], &edge[i],
                           blocks ? blocks + (size_t)i * SPREAD_BLOCKS : NULL, median ? &median[i] : &mi);
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

/* The direction's uncertainty: the edge scores on a 1 degree grid within 6 degrees of best, per
 * block of consecutive pairs; over SPREAD_DRAWS draws of the blocks with replacement the best
 * direction's RMS angle from best, in degrees (0 when the grid has fewer than 2 directions).
 * -1 out of memory. */
static int direction_spread(const search_ctx *c, rs_v3 best, double tau, rs_v3 *dirs, double *med, double *edge,
                            size_t *np, double *sigma_deg)
{
    *sigma_deg = 0;
    int n = local_grid(c->env, best, 6 * DEG, 1 * DEG, dirs);
    if (n < 2) return 0;
    double *blocks = malloc((size_t)n * SPREAD_BLOCKS * sizeof *blocks);
    if (!blocks || score_all(c, dirs, n, tau, med, edge, np, NULL, blocks) != 0) {
        free(blocks);
        return -1;
    }
    uint32_t rng = 0x9e3779b9u, pick[SPREAD_BLOCKS];
    double sum2 = 0;
    for (int draw = 0; draw < SPREAD_DRAWS; draw++) {
        for (int k = 0; k < SPREAD_BLOCKS; k++) {
            rng = rng * 1664525u + 1013904223u;
            pick[k] = (rng >> 8) % SPREAD_BLOCKS;
        }
        int top = -1;
        double top_sc = -INFINITY;
        for (int i = 0; i < n; i++) {
            if (!isfinite(edge[i])) continue;
            double sc = 0;
            for (int k = 0; k < SPREAD_BLOCKS; k++) sc += blocks[(size_t)i * SPREAD_BLOCKS + pick[k]];
            if (sc > top_sc) {
                top_sc = sc;
                top = i;
            }
        }
        double ang = top < 0 ? 0 : acos(fmax(-1, fmin(1, rs_v3_dot(dirs[top], best))));
        sum2 += ang * ang;
    }
    *sigma_deg = sqrt(sum2 / SPREAD_DRAWS) / DEG;
    free(blocks);
    return 0;
}

/* The best three of dirs[0..n) by edges, at least 8 degrees apart, each refined at 2 then 0.5
 * degrees; the best of all into out. Returns whether one was found, -1 out of memory. */
static int refine(const search_ctx *c, rs_v3 *dirs, int n, double tau, double *med, double *edge, size_t *np,
                  double *median, rs_sunsearch *out)
{
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
            int nl = local_grid(c->env, centre, level ? 2 * DEG : 8 * DEG, level ? 0.5 * DEG : 2 * DEG, dirs);
            if (score_all(c, dirs, nl, tau, med, edge, np, median, NULL) != 0) return -1;
            out->candidates += nl;
            int i = best_apart(dirs, edge, nl, NULL, 0, 0);
            if (i < 0) break;
            centre = dirs[i];
            if (edge[i] > best) {
                best = edge[i];
                out->dir = dirs[i];
                out->score = med[i];
                out->median_score = median[i];
                out->edge_score = edge[i];
                out->pairs = np[i];
            }
        }
    }
    return isfinite(best);
}

/* Total and standard error, over the SPREAD_BLOCKS blocks of consecutive pairs, of the
 * difference a - b of two directions' per-block edge scores (paired: the same pairs). */
static void block_difference(const double *a, const double *b, double *sum, double *se)
{
    double s = 0, s2 = 0;
    for (int k = 0; k < SPREAD_BLOCKS; k++) {
        double d = a[k] - b[k];
        s += d;
        s2 += d * d;
    }
    double var = (s2 - s * s / SPREAD_BLOCKS) / (SPREAD_BLOCKS - 1);
    *sum = s;
    *se = sqrt(fmax(0, var) * SPREAD_BLOCKS);
}

/* Refines *centre at 2 and then 0.5 degrees, among the directions inside the cone (and the
 * centre itself); *centre becomes each level's best. Returns the best's index in dirs (its scores
 * in med, edge, np, median), -2 when a level has no best, -1 out of memory. */
static int refine_in_cone(const search_ctx *c, const cone *k, double tau, rs_v3 *centre, rs_v3 *dirs, double *med,
                          double *edge, size_t *np, double *median, rs_sunsearch *out)
{
    int best = -2;
    for (int level = 0; level < 2; level++) {
        int nl = local_grid(c->env, *centre, level ? 2 * DEG : 4 * DEG, level ? 0.5 * DEG : 2 * DEG, dirs), m = 0;
        for (int i = 0; i < nl; i++)
            if (rs_v3_dot(dirs[i], *k->prior) >= k->cos_cone) dirs[m++] = dirs[i];
        dirs[m++] = *centre;
        if (score_all(c, dirs, m, tau, med, edge, np, median, NULL) != 0) return -1;
        out->candidates += m;
        best = best_apart(dirs, edge, m, NULL, 0, 0);
        if (best < 0) return -2;
        *centre = dirs[best];
    }
    return best;
}

/* No direction inside the cone is tied with the best (ridge_in_cone): by how much does the best
 * beat the cone? The coarse in-cone directions dirs[1..n) keep their edge scores in edge; the
 * best of them is refined at 2 and 0.5 degrees within the cone (its best chance), and the best's
 * edge-score lead over it, in block standard errors, goes to out->cone_sigmas (its direction to
 * out->cone_dir). INFINITY when no direction inside has a score (too few lit-shadowed pairs, or
 * no sun's cluster of contrasts: the shadows support none of them); NAN when the cone holds no
 * hidden direction at all (nothing to compare with). Returns 0, -1 out of memory. */
static int cone_margin(const search_ctx *c, const cone *k, double tau, rs_v3 *dirs, double *med, double *edge,
                       size_t *np, double *median, int n, rs_sunsearch *out)
{
    int top = -1;
    for (int i = 1; i < n; i++)
        if (isfinite(edge[i]) && (top < 0 || edge[i] > edge[top])) top = i;
    if (top < 0) { /* no direction inside casts a sun's shadows onto the observed model */
        if (n > 1) out->cone_sigmas = INFINITY;
        return 0;
    }
    rs_v3 centre = dirs[top];
    if (refine_in_cone(c, k, tau, &centre, dirs, med, edge, np, median, out) == -1) return -1;
    double blocks[2 * SPREAD_BLOCKS], sum, se;
    dirs[0] = out->dir;
    dirs[1] = centre;
    if (score_all(c, dirs, 2, tau, med, edge, np, median, blocks) != 0) return -1;
    out->candidates += 2;
    out->cone_dir = centre;
    if (!isfinite(edge[1])) return 0;
    block_difference(blocks, blocks + SPREAD_BLOCKS, &sum, &se);
    out->cone_sigmas = se > 0 ? sum / se : sum > 0 ? INFINITY : 0;
    return 0;
}

/* The best direction lies beyond the cone around the visible sky's sun, but the shadows' score is
 * flat along a ridge of directions that put the long shadow lines in the same place (in a
 * street whose far ends the scan lacks, azimuth and elevation trade along the whole street).
 * Among the coarse directions inside the cone, those whose edge score is statistically tied
 * with the best (the total over blocks of pairs of their difference below 2 standard errors)
 * could be the sun as well as it: the one nearest the prior is refined at 2 and 0.5 degrees
 * within the cone and replaces the best (out->ridge). Returns 1 when it did, 0 when none is
 * tied (cone_margin then measures the best's lead), -1 out of memory. */
static int ridge_in_cone(const search_ctx *c, const cone *k, double tau, rs_v3 *dirs, double *med, double *edge,
                         size_t *np, double *median, rs_sunsearch *out)
{
    int n = 1;
    dirs[0] = out->dir;
    for (double el = 4 * DEG; el < 88 * DEG && n < 4000; el += 4 * DEG) {
        int naz = (int)fmax(1, round(360 * cos(el) / 4));
        for (int a = 0; a < naz && n < 4000; a++) {
            double az = 2 * M_PI * a / naz;
            rs_v3 d = rs_v3_make(cos(el) * cos(az), cos(el) * sin(az), sin(el));
            if (hidden(c->env, d) && rs_v3_dot(d, *k->prior) >= k->cos_cone) dirs[n++] = d;
        }
    }
    double *blocks = malloc((size_t)n * SPREAD_BLOCKS * sizeof *blocks);
    if (!blocks || score_all(c, dirs, n, tau, med, edge, np, median, blocks) != 0) {
        free(blocks);
        return -1;
    }
    out->candidates += n;
    int pick = -1;
    double pick_cos = -2;
    for (int i = 1; i < n; i++) {
        if (!isfinite(edge[i])) continue;
        double sum, se;
        block_difference(blocks, blocks + (size_t)i * SPREAD_BLOCKS, &sum, &se);
        double cosp = rs_v3_dot(dirs[i], *k->prior);
        if (sum < 2 * se && cosp > pick_cos) {
            pick = i;
            pick_cos = cosp;
        }
    }
    free(blocks);
    if (pick < 0) return cone_margin(c, k, tau, dirs, med, edge, np, median, n, out);
    rs_v3 centre = dirs[pick];
    int best = refine_in_cone(c, k, tau, &centre, dirs, med, edge, np, median, out);
    if (best == -1) return -1;
    if (best < 0) return 0;
    out->dir = dirs[best];
    out->score = med[best];
    out->median_score = median[best];
    out->edge_score = edge[best];
    out->pairs = np[best];
    out->ridge = 1;
    return 1;
}

/* Of the pair facets with albedo above RS_SUNSHADOW_ABOVE_ONE without the sun, those that
 * direction s lights and those it shadows (one ray from the centroid). -1 out of memory. */
static int above_one_counts(const search_ctx *c, rs_v3 s, size_t *lit, size_t *dark)
{
    *lit = *dark = 0;
    double excess_log = log(RS_SUNSHADOW_ABOVE_ONE / M_PI);
    rs_ray *rays = malloc((c->nfacets + 1) * sizeof *rays);
    uint8_t *occl = malloc(c->nfacets + 1);
    if (!rays || !occl) {
        free(rays);
        free(occl);
        return -1;
    }
    size_t nr = 0;
    for (size_t k = 0; k < c->nfacets; k++)
        if (rs_v3_dot(c->nrm[k], s) > 0.1 && c->log_ratio[c->facets[k]] > excess_log)
            rays[nr++] = (rs_ray){.org = c->org[k], .dir = s, .tnear = 0, .tfar = INFINITY};
    rs_scene_occluded(c->scene, rays, occl, nr);
    for (size_t r = 0; r < nr; r++) {
        *lit += !occl[r];
        *dark += occl[r] != 0;
    }
    free(rays);
    free(occl);
    return 0;
}

static int search_run(const rs_scene *scene, const rs_skyenv *env, const rs_sunshadow_pairs *pairs, const double *E,
                      const double *L, const uint8_t *observed, int allow_upper, const cone *k, rs_sunsearch *out,
                      rs_err *err)
{
    memset(out, 0, sizeof *out);
    out->cone_sigmas = NAN;
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
    search_ctx c = {.scene = scene, .env = env, .pairs = pairs, .forgive = allow_upper};
    c.slot = malloc((nf ? nf : 1) * sizeof *c.slot);
    c.facets = malloc((nf ? nf : 1) * sizeof *c.facets);
    c.org = malloc((nf ? nf : 1) * sizeof *c.org);
    c.nrm = malloc((nf ? nf : 1) * sizeof *c.nrm);
    c.log_ratio = malloc((nf ? nf : 1) * sizeof *c.log_ratio);
    int cap = 4096, rc = -1;
    rs_v3 *dirs = malloc(cap * sizeof *dirs);
    double *med = malloc(cap * sizeof *med), *edge = malloc(cap * sizeof *edge), *median = malloc(cap * sizeof *median);
    size_t *np = malloc(cap * sizeof *np);
    if (!c.slot || !c.facets || !c.org || !c.nrm || !c.log_ratio || !dirs || !med || !edge || !median || !np) goto done;
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
    if (score_all(&c, dirs, n, 0, med, edge, np, NULL, NULL) != 0) goto done;
    out->candidates = n;
    int top = best_apart(dirs, med, n, NULL, 0, 0);
    if (top < 0) {
        rc = 1; /* no direction had enough pairs */
        goto done;
    }
    if (allow_upper && med[top] < RS_SUNSEARCH_MIN_SCORE) { /* perhaps outvoted by leaks: the sun's cluster instead */
        c.upper = 1;
        if (score_all(&c, dirs, n, 0, med, edge, np, NULL, NULL) != 0) goto done;
        out->candidates += n;
        top = best_apart(dirs, med, n, NULL, 0, 0);
        if (top < 0) {
            rc = 1; /* no direction's contrasts have a sun's cluster */
            goto done;
        }
    }
    out->upper_cluster = c.upper;
    double tau = 0.5 * med[top];
    if (score_all(&c, dirs, n, tau, med, edge, np, NULL, NULL) != 0) goto done;
    out->candidates += n;
    rc = refine(&c, dirs, n, tau, med, edge, np, median, out);
    if (rc == 1 && k->prior && rs_v3_dot(out->dir, *k->prior) < k->cos_cone &&
        ridge_in_cone(&c, k, tau, dirs, med, edge, np, median, out) < 0)
        rc = -1;
    if (rc == 1 &&
        (direction_spread(&c, out->dir, tau, dirs, med, edge, np, &out->dir_sigma_deg) != 0 ||
         above_one_counts(&c, out->dir, &out->above_one_lit, &out->above_one_dark) != 0))
        rc = -1;
    if (rc >= 0) rc = rc == 1 ? 0 : 1;
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
    free(median);
    free(np);
    if (rc < 0) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory searching the shadows for the sun");
    return rc;
}

int rs_sunsearch_run(const rs_scene *scene, const rs_skyenv *env, const rs_sunshadow_pairs *pairs, const double *E,
                     const double *L, const uint8_t *observed, const rs_v3 *prior, double prior_deg, rs_sunsearch *out,
                     rs_err *err)
{
    cone k = {.prior = prior, .cos_cone = cos(prior_deg * DEG)};
    return search_run(scene, env, pairs, E, L, observed, 1, &k, out, err);
}

int rs_sunsearch_run_median_only(const rs_scene *scene, const rs_skyenv *env, const rs_sunshadow_pairs *pairs,
                                 const double *E, const double *L, const uint8_t *observed, rs_sunsearch *out,
                                 rs_err *err)
{
    cone k = {.prior = NULL};
    return search_run(scene, env, pairs, E, L, observed, 0, &k, out, err);
}

int rs_sunsearch_accept(const rs_sunsearch *f, double off_deg, double agree_deg, double lead_sigmas, int *missing_light,
                        int *decisive)
{
    *missing_light = f->above_one_lit >= RS_SUNSEARCH_MIN_ABOVE_ONE && f->above_one_lit >= 4 * f->above_one_dark;
    *decisive = lead_sigmas > 0 && f->cone_sigmas >= lead_sigmas && f->above_one_lit >= RS_SUNSEARCH_MIN_ABOVE_ONE &&
        f->above_one_lit > f->above_one_dark;
    return f->score >= RS_SUNSEARCH_MIN_SCORE && (off_deg <= agree_deg || *missing_light || *decisive);
}

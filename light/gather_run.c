/* gather_run: the gather of a whole model (rs_gather_run, gather.h): facets in Morton order on
 * all OpenMP threads of every MPI rank, the closure of the light paths that end at the facets a camera sees, and
 * the Monte Carlo noise calibration that gathers a sample of facets again. */
#include "light/gather.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/log.h"
#include "common/par.h"
#include "light/gather_share.h"

/* Morton code of a point scaled into [0, 1)^3: 10 bits per axis, interleaved. */
static uint32_t spread10(uint32_t v)
{
    v &= 0x3ff;
    v = (v | (v << 16)) & 0x030000ff;
    v = (v | (v << 8)) & 0x0300f00f;
    v = (v | (v << 4)) & 0x030c30c3;
    v = (v | (v << 2)) & 0x09249249;
    return v;
}

typedef struct {
    uint32_t code, face;
} morton_key;

static int cmp_morton(const void *a, const void *b)
{
    const morton_key *x = a, *y = b;
    if (x->code != y->code) return x->code < y->code ? -1 : 1;
    return (x->face > y->face) - (x->face < y->face);
}

/* Facet indices in the Morton order of their centroids (ties by index): nf entries, caller frees. */
static uint32_t *morton_order(const rs_mesh *m, size_t nf)
{
    morton_key *keys = malloc(nf * sizeof *keys);
    uint32_t *order = malloc(nf * sizeof *order);
    if (!keys || !order) {
        free(keys);
        free(order);
        return NULL;
    }
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < m->nverts; v++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fminf(lo[a], m->verts[3 * v + a]);
            hi[a] = fmaxf(hi[a], m->verts[3 * v + a]);
        }
    for (size_t f = 0; f < nf; f++) {
        uint32_t q[3];
        for (int a = 0; a < 3; a++) {
            double c = 0;
            for (int k = 0; k < 3; k++) c += m->verts[3 * (size_t)m->tris[3 * f + k] + a] / 3.0;
            double t = hi[a] > lo[a] ? (c - lo[a]) / (hi[a] - lo[a]) : 0;
            q[a] = (uint32_t)fmin(1023, fmax(0, t * 1024));
        }
        keys[f].code = spread10(q[0]) | spread10(q[1]) << 1 | spread10(q[2]) << 2;
        keys[f].face = (uint32_t)f;
    }
    qsort(keys, nf, sizeof *keys, cmp_morton);
    for (size_t k = 0; k < nf; k++) order[k] = keys[k].face;
    free(keys);
    return order;
}

/* Facets per block of the work queue: neighbours in the Morton order share BVH nodes in the
 * cache, and a block is small against a rank's share (costs differ a lot: a roof's rays escape
 * at once, a courtyard's bounce). */
#define RS_GATHER_BLOCK 16

/* Gathers the listed facets in parallel into fg[list[k]], or into fg[k] when by_position; -1 when
 * a thread ran out of memory. Blocks of the list go to whichever thread, of whichever MPI rank
 * (common/par.h), asks first; the ranks then exchange what they gathered (gather_share.h). */
static int gather_list(const rs_gather_ctx *g, const uint32_t *list, size_t n, rs_facet_gather *fg, int by_position,
                       struct rs_progress *prog)
{
    size_t scratch = (size_t)g->samples;
    if ((size_t)g->sky_samples > scratch) scratch = (size_t)g->sky_samples;
    if ((size_t)g->sun_samples > scratch) scratch = (size_t)g->sun_samples;
    int ranks = rs_par_size() > 1;
    uint8_t *mine = ranks ? calloc(n ? n : 1, 1) : NULL;
    rs_par_queue *queue = rs_par_queue_new(n, RS_GATHER_BLOCK);
    int failed = !queue || (ranks && !mine);
#pragma omp parallel
    {
        rs_gather_scratch *s = rs_gather_scratch_new(scratch);
        int mine_failed = !s;
        size_t begin, end;
        while (!mine_failed && !failed && queue && rs_par_queue_take(queue, &begin, &end)) {
            for (size_t k = begin; k < end && !mine_failed; k++) {
                if (rs_gather_facet(g, list[k], s, &fg[by_position ? k : list[k]]) != 0) mine_failed = 1;
                if (mine) mine[k] = 1;
            }
            if (prog) rs_progress_add(prog, (end - begin) * (size_t)rs_par_size());
        }
        if (mine_failed) {
#pragma omp atomic write
            failed = 1;
        }
        rs_gather_scratch_free(s);
    }
    rs_par_queue_free(queue);
    if (ranks && !rs_par_any(failed)) failed = rs_gather_share(list, n, fg, by_position, mine) != 0;
    free(mine);
    return rs_par_any(failed) ? -1 : 0;
}

/* Every failure of the gather's entry points (their steps return a bare -1). */
static int gather_out_of_memory(rs_err *err)
{
    return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory during the gather");
}

int rs_gather_list(const rs_gather_ctx *g, const uint32_t *list, size_t n, rs_facet_gather *out, rs_err *err)
{
    memset(out, 0, n * sizeof *out);
    return gather_list(g, list, n, out, 1, NULL) != 0 ? gather_out_of_memory(err) : 0;
}

/* count x share rounded down to a power of two (Sobol stratifies best there), and at least 1
 * when count is, so that every kind of ray in use stays in use. */
static int relay_count(int count, double share)
{
    if (count <= 0) return count;
    double want = count * share;
    int n = 1;
    while (2.0 * n <= want) n *= 2;
    return n < count ? n : count;
}

int rs_gather_run(const rs_gather_ctx *g, size_t nf, const uint8_t *needed, rs_facet_gather *fg, uint8_t *gathered,
                  struct rs_progress *prog, rs_gather_stats *stats, rs_err *err)
{
    memset(stats, 0, sizeof *stats);
    memset(fg, 0, nf * sizeof *fg);
    uint32_t *order = morton_order(rs_scene_mesh(g->scene), nf), *list = malloc((nf ? nf : 1) * sizeof *list);
    uint8_t *state = calloc(nf ? nf : 1, 1); /* 0 not reached, 1 queued, 2 gathered */
    int rc = -1;
    if (!order || !list || !state) goto out;
    for (size_t f = 0; f < nf; f++) state[f] = !needed || needed[f];
    /* Relays (every wave after the first) matter only through the K_ij L_j sums of the facets
     * they light, which average over many relays: their own noise needs fewer rays, and no
     * rounds to bring it down. */
    rs_gather_ctx relay = *g;
    int relays = g->relay_share > 0 && g->relay_share < 1;
    if (relays) {
        relay.samples = relay_count(g->samples, g->relay_share);
        relay.sky_samples = relay_count(g->sky_samples, g->relay_share);
        relay.sun_samples = relay_count(g->sun_samples, g->relay_share);
        relay.target_error = relay.sun_target_error = 0;
    }
    for (;;) {
        size_t n = 0;
        for (size_t k = 0; k < nf; k++)
            if (state[order[k]] == 1) list[n++] = order[k];
        if (!n) break;
        if (gather_list(stats->waves ? &relay : g, list, n, fg, 0, prog) != 0) goto out;
        if (relays && stats->waves) {
            for (size_t k = 0; k < n; k++) fg[list[k]].relay = 1;
            stats->relays += n;
        }
        stats->waves++;
        stats->gathered += n;
        for (size_t k = 0; k < n; k++) state[list[k]] = 2;
        for (size_t k = 0; k < n; k++) /* what these facets' rays reached comes next */
            for (uint32_t q = 0; q < fg[list[k]].nentries; q++)
                if (!state[fg[list[k]].entries[q].col]) state[fg[list[k]].entries[q].col] = 1;
    }
    for (size_t f = 0; f < nf; f++) {
        stats->rays += fg[f].sees_nothing ? 0 : fg[f].rays;
        stats->sees_nothing += fg[f].sees_nothing;
    }
    if (gathered)
        for (size_t f = 0; f < nf; f++) gathered[f] = state[f] == 2;
    rc = 0;
out:
    free(order);
    free(list);
    free(state);
    return rc != 0 ? gather_out_of_memory(err) : 0;
}

/* Luminance of E_sky + G with G's K part from observed facets' radiance (as rs_gather_mc_sigma). */
static double facet_lum(const rs_facet_gather *fg, const double *radiance, const uint8_t *observed)
{
    double e = fg->esky_lum + 0.2126 * fg->gseen[0] + 0.7152 * fg->gseen[1] + 0.0722 * fg->gseen[2];
    for (uint32_t q = 0; radiance && q < fg->nentries; q++) {
        const rs_kentry *en = &fg->entries[q];
        if (observed && !observed[en->col]) continue;
        const double *L = radiance + 3 * (size_t)en->col;
        e += en->k_unseen * (0.2126 * L[0] + 0.7152 * L[1] + 0.0722 * L[2]);
    }
    return e;
}

int rs_gather_mc_calibration(const rs_gather_ctx *g, size_t nf, const rs_facet_gather *fg, const double *radiance,
                             const uint8_t *observed, size_t max_facets, double *factor, size_t *used, rs_err *err)
{
    *factor = 1;
    if (used) *used = 0;
    size_t n = 0;
    /* Not relays: the second gather, at g's counts, must repeat the first. */
    for (size_t f = 0; f < nf; f++) n += fg[f].rays > 0 && !fg[f].relay;
    if (!n || !max_facets) return 0;
    size_t stride = (n + max_facets - 1) / max_facets, m = 0;
    uint32_t *list = malloc(((n + stride - 1) / stride + 1) * sizeof *list);
    rs_facet_gather *again = calloc((n + stride - 1) / stride + 1, sizeof *again);
    if (!list || !again) {
        free(list);
        free(again);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory measuring the gather's noise");
    }
    for (size_t f = 0, k = 0; f < nf; f++)
        if (fg[f].rays > 0 && !fg[f].relay && k++ % stride == 0) list[m++] = (uint32_t)f;
    rs_gather_ctx g2 = *g;
    g2.seed = g->seed ^ 0x5bd1e995u; /* an independent scrambling */
    int rc = gather_list(&g2, list, m, again, 1, NULL);
    double sum = 0;
    size_t cnt = 0;
    for (size_t k = 0; k < m; k++) {
        const rs_facet_gather *a = &fg[list[k]], *b = &again[k];
        double sa = rs_gather_mc_sigma(a, radiance, observed);
        double sb = rs_gather_mc_sigma(b, radiance, observed);
        double d = facet_lum(a, radiance, observed) - facet_lum(b, radiance, observed);
        if (rc == 0 && sa + sb > 0) {
            sum += d * d / (sa * sa + sb * sb); /* var(E - E') = sa^2 + sb^2 */
            cnt++;
        }
        free(again[k].entries);
    }
    free(list);
    free(again);
    if (rc != 0) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory measuring the gather's noise");
    if (cnt) *factor = sqrt(sum / cnt);
    if (used) *used = cnt;
    return 0;
}

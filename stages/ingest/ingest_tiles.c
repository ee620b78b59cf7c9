/* ingest_tiles: the streaming path's cleaning, statistical outlier removal then the voxel grid,
 * on spatial tiles, so that the cloud is never held whole. A coarse grid of cells (GRID_CELLS
 * along the box's longest side; with a voxel grid, cells are whole voxels of PCL's own voxel
 * arithmetic, so no voxel straddles two tiles) is counted in one pass; tiles are blocks of cells
 * small enough to hold at most tile_budget() points. A batch of consecutive tiles (at most four
 * tiles' worth of points) is gathered in one pass over the files: each tile's own points plus
 * the points within a margin of it, from which each own point's k nearest neighbours are found
 * with the whole-cloud path's arithmetic (rs_pcl_knn_mean). A point whose kth neighbour lies
 * farther than the margin could see is resolved afterwards from every point within that
 * distance (the fallback), so every point gets its mean distance over its true k neighbours.
 * The distances go to a temporary file in runs sorted by point; merged back into the files'
 * order they give PCL's mean and standard deviation with PCL's summation order, hence its
 * threshold, bit for bit. Outliers are marked in the coincident bitmap; the voxel grid then runs
 * per tile on the survivors. Exports rs_ingest_clean_stream (ingest_stream.h). */
#include "stages/ingest/ingest_stream.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "common/cloud_ply.h"
#include "common/log.h"
#include "common/pcl_bridge.h"

#define GRID_CELLS 128 /* cells along the longest side of the points' box */
#define MAX_DIM    (GRID_CELLS + 2)

/* Points a tile holds at most (unless one cell holds more); a batch is four tiles' worth. The
 * environment variable RHOSCAN_INGEST_TILE_POINTS sets a smaller one (the tests). */
static size_t tile_budget(void)
{
    const char *v = getenv("RHOSCAN_INGEST_TILE_POINTS");
    long n = v ? strtol(v, NULL, 10) : 0;
    return n >= 16 && n <= (1L << 24) ? (size_t)n : (size_t)1 << 20;
}

static long floor_div(long a, long b)
{
    long q = a / b;
    return (a % b != 0 && (a < 0) != (b < 0)) ? q - 1 : q;
}

typedef struct grid {
    int voxel;           /* cells are whole voxels */
    double leaf;         /* the voxel size */
    float inv_leaf;      /* 1 / leaf in float, as PCL's VoxelGrid has it */
    long vcell;          /* voxels a cell */
    long vorigin[3];     /* the voxel index where cell 0 starts */
    double origin[3];    /* cell 0's corner, metres */
    double cell;         /* a cell's side, metres */
    long dim[3], b;      /* cells along each axis; a tile is b x b x b cells */
    long tdim[3];        /* tiles along each axis */
    double lo[3], hi[3]; /* the points' box */
    uint32_t *count;     /* points a cell */
    size_t *tcount;      /* points a tile */
    int k;               /* neighbours (0: no outlier removal) */
} grid;

typedef struct rec {
    uint32_t g; /* the point's place among the streamed points */
    float d;    /* its mean distance to its k neighbours */
} rec;

typedef struct ctx {
    const rs_config *cfg;
    source *s;
    coincident *co;
    grid gr;
    FILE *tmp; /* runs of rec sorted by g */
    long *run_off;
    size_t *run_n, nruns, cap_runs;
    rec *out; /* the current batch's records */
    size_t nout, cap_out;
    rec *fail_r; /* points the margin did not settle: g, and in fail_p their position and radius */
    float *fail_p;
    size_t nfail, cap_fail;
} ctx;

static int is_dropped(const coincident *co, size_t g)
{
    return co->dropped[g >> 3] >> (g & 7) & 1;
}

static long vox(const grid *gr, double x)
{
    float xf = (float)x; /* PCL: floor(p.x * inverse_leaf_size_) in float */
    return (long)floorf(xf * gr->inv_leaf);
}

static void grid_setup(grid *gr, const rs_config *cfg, const double lo[3], const double hi[3])
{
    double ext = 0;
    memcpy(gr->lo, lo, sizeof gr->lo), memcpy(gr->hi, hi, sizeof gr->hi);
    for (int j = 0; j < 3; j++) ext = fmax(ext, hi[j] - lo[j]);
    if (!(ext > 0)) ext = 1;
    double target = ext / GRID_CELLS;
    gr->voxel = rs_config_has(cfg, "ingest", "voxel_size");
    if (gr->voxel) {
        gr->leaf = rs_config_real(cfg, "ingest", "voxel_size");
        gr->inv_leaf = 1.0f / (float)gr->leaf;
        gr->vcell = 1;
        while ((double)gr->vcell * gr->leaf < target && gr->vcell < (1L << 40)) gr->vcell *= 2;
        gr->cell = (double)gr->vcell * gr->leaf;
        for (int j = 0; j < 3; j++) {
            gr->vorigin[j] = floor_div(vox(gr, lo[j]), gr->vcell) * gr->vcell;
            gr->dim[j] = floor_div(vox(gr, hi[j]) - gr->vorigin[j], gr->vcell) + 1;
            gr->origin[j] = (double)gr->vorigin[j] * gr->leaf;
        }
    } else {
        double c = 1; /* a power of two: tile boundaries at round coordinates */
        while (c < target) c *= 2;
        while (c / 2 >= target) c /= 2;
        gr->cell = c;
        for (int j = 0; j < 3; j++) {
            gr->origin[j] = floor(lo[j] / c) * c;
            gr->dim[j] = (long)floor((hi[j] - gr->origin[j]) / c) + 1;
        }
    }
    for (int j = 0; j < 3; j++) gr->dim[j] = gr->dim[j] < 1 ? 1 : gr->dim[j] > MAX_DIM ? MAX_DIM : gr->dim[j];
}

/* The cell of p (clamped into the grid, so every pass puts a point in the same one). */
static size_t cell_of(const grid *gr, const double p[3], long c[3])
{
    for (int j = 0; j < 3; j++) {
        long v = gr->voxel ? floor_div(vox(gr, p[j]) - gr->vorigin[j], gr->vcell)
                           : (long)floor((p[j] - gr->origin[j]) / gr->cell);
        c[j] = v < 0 ? 0 : v >= gr->dim[j] ? gr->dim[j] - 1 : v;
    }
    return (size_t)((c[2] * gr->dim[1] + c[1]) * gr->dim[0] + c[0]);
}

static size_t tile_index(const grid *gr, const long t[3])
{
    return (size_t)((t[2] * gr->tdim[1] + t[1]) * gr->tdim[0] + t[0]);
}

static size_t ntiles(const grid *gr)
{
    return (size_t)(gr->tdim[0] * gr->tdim[1] * gr->tdim[2]);
}

/* Tile t's box in metres (its cells'; with voxels, up to float rounding). */
static void tile_box(const grid *gr, size_t t, double lo[3], double hi[3])
{
    long tc[3] = {(long)(t % (size_t)gr->tdim[0]), (long)(t / (size_t)gr->tdim[0] % (size_t)gr->tdim[1]),
                  (long)(t / (size_t)(gr->tdim[0] * gr->tdim[1]))};
    for (int j = 0; j < 3; j++) {
        lo[j] = gr->origin[j] + (double)(tc[j] * gr->b) * gr->cell;
        hi[j] = lo[j] + (double)gr->b * gr->cell;
    }
}

/* The count pass, then the largest tiles (b a power of two) holding at most the budget. */
static int count_cells(ctx *x, rs_err *err)
{
    grid *gr = &x->gr;
    size_t ncells = (size_t)(gr->dim[0] * gr->dim[1] * gr->dim[2]), g = 0;
    gr->count = calloc(ncells, sizeof *gr->count);
    if (!gr->count) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the tile grid");
    int r;
    long c[3];
    rs_ingest_source_rewind(x->s);
    while ((r = rs_ingest_source_next(x->s, err)) > 0)
        for (size_t i = 0; i < x->s->n; i++, g++)
            if (!is_dropped(x->co, g)) gr->count[cell_of(gr, x->s->xyz + 3 * i, c)]++;
    if (r < 0) return -1;
    long maxdim = gr->dim[0] > gr->dim[1] ? gr->dim[0] : gr->dim[1];
    maxdim = maxdim > gr->dim[2] ? maxdim : gr->dim[2];
    for (gr->b = 1; gr->b < maxdim;) gr->b *= 2;
    for (;; gr->b /= 2) {
        for (int j = 0; j < 3; j++) gr->tdim[j] = (gr->dim[j] + gr->b - 1) / gr->b;
        free(gr->tcount);
        gr->tcount = calloc(ntiles(gr), sizeof *gr->tcount);
        if (!gr->tcount) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the tile grid");
        size_t most = 0;
        for (long z = 0; z < gr->dim[2]; z++)
            for (long y = 0; y < gr->dim[1]; y++)
                for (long xx = 0; xx < gr->dim[0]; xx++) {
                    long t[3] = {xx / gr->b, y / gr->b, z / gr->b};
                    size_t *tc = &gr->tcount[tile_index(gr, t)];
                    *tc += gr->count[(size_t)((z * gr->dim[1] + y) * gr->dim[0] + xx)];
                    most = *tc > most ? *tc : most;
                }
        if (most <= tile_budget() || gr->b == 1) break;
    }
    return 0;
}

/* One tile's gathered points: its own (g set) and its margin's (g = UINT32_MAX). */
typedef struct tpts {
    float *xyz;
    uint32_t *g;
    size_t n, cap, own;
    double lo[3], hi[3], m; /* its box and margin */
} tpts;

static int tpts_push(tpts *tp, const double p[3], uint32_t g)
{
    if (tp->n == tp->cap) {
        size_t cap = tp->cap ? 2 * tp->cap : 1024;
        float *xyz = realloc(tp->xyz, 3 * cap * sizeof *xyz);
        if (xyz) tp->xyz = xyz;
        uint32_t *gg = realloc(tp->g, cap * sizeof *gg);
        if (gg) tp->g = gg;
        if (!xyz || !gg) return -1;
        tp->cap = cap;
    }
    for (int j = 0; j < 3; j++) tp->xyz[3 * tp->n + j] = (float)p[j];
    tp->g[tp->n++] = g;
    tp->own += g != UINT32_MAX;
    return 0;
}

static int push_rec(rec **buf, size_t *n, size_t *cap, rec r)
{
    if (*n == *cap) {
        size_t c = *cap ? 2 * *cap : 4096;
        rec *b = realloc(*buf, c * sizeof *b);
        if (!b) return -1;
        *buf = b, *cap = c;
    }
    (*buf)[(*n)++] = r;
    return 0;
}

static int push_fail(ctx *x, uint32_t g, const float p[3], float radius)
{
    size_t n = x->nfail, cap = x->cap_fail;
    if (push_rec(&x->fail_r, &x->nfail, &x->cap_fail, (rec){g, radius}) != 0) return -1;
    if (x->cap_fail != cap) {
        float *fp = realloc(x->fail_p, 3 * x->cap_fail * sizeof *fp);
        if (!fp) return -1;
        x->fail_p = fp;
    }
    memcpy(x->fail_p + 3 * n, p, 3 * sizeof *p);
    return 0;
}

/* The rounding a float coordinate (and a distance between floats) may carry. */
static double slack_of(const float p[3])
{
    return 1e-6 * (fabs(p[0]) + fabs(p[1]) + fabs(p[2]) + 1);
}

static int cmp_rec(const void *a, const void *b)
{
    uint32_t x = ((const rec *)a)->g, y = ((const rec *)b)->g;
    return (x > y) - (x < y);
}

/* The batch's records, sorted by point, as one run of the temporary file. */
static int flush_run(ctx *x, rs_err *err)
{
    if (x->nout == 0) return 0;
    qsort(x->out, x->nout, sizeof *x->out, cmp_rec);
    if (x->nruns == x->cap_runs) {
        size_t c = x->cap_runs ? 2 * x->cap_runs : 64;
        long *o = realloc(x->run_off, c * sizeof *o);
        if (o) x->run_off = o;
        size_t *n = realloc(x->run_n, c * sizeof *n);
        if (n) x->run_n = n;
        if (!o || !n) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        x->cap_runs = c;
    }
    if (fseek(x->tmp, 0, SEEK_END) != 0) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "seek in a temporary file");
    x->run_off[x->nruns] = ftell(x->tmp);
    x->run_n[x->nruns++] = x->nout;
    if (fwrite(x->out, sizeof *x->out, x->nout, x->tmp) != x->nout)
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0,
                          "cannot write the neighbour distances' temporary file (disk full?)");
    x->nout = 0;
    return 0;
}

/* kNN of one tile's own points among its gathered ones; those whose kth neighbour is closer than
 * the box the margin gathered (the points' box's faces have nothing beyond) are settled. */
static int tile_knn(ctx *x, tpts *tp, rs_err *err)
{
    size_t own = tp->own, m = 0;
    float *q = malloc((own ? own : 1) * 3 * sizeof *q), *mean = malloc((own ? own : 1) * sizeof *mean),
          *kth = malloc((own ? own : 1) * sizeof *kth);
    uint32_t *qg = malloc((own ? own : 1) * sizeof *qg);
    int rc = -1;
    if (!q || !mean || !kth || !qg) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for a tile");
        goto out;
    }
    for (size_t i = 0; i < tp->n; i++)
        if (tp->g[i] != UINT32_MAX) memcpy(q + 3 * m, tp->xyz + 3 * i, 3 * sizeof *q), qg[m++] = tp->g[i];
    if (rs_pcl_knn_mean(tp->xyz, tp->n, q, own, x->gr.k, mean, kth, err) != 0) goto out;
    for (size_t i = 0; i < own; i++) {
        const float *p = q + 3 * i;
        double reach = INFINITY, slack = slack_of(p);
        for (int j = 0; j < 3; j++) {
            if (tp->lo[j] - tp->m > x->gr.lo[j]) reach = fmin(reach, p[j] - (tp->lo[j] - tp->m));
            if (tp->hi[j] + tp->m < x->gr.hi[j]) reach = fmin(reach, tp->hi[j] + tp->m - p[j]);
        }
        int bad;
        if (kth[i] <= reach - slack)
            bad = push_rec(&x->out, &x->nout, &x->cap_out, (rec){qg[i], mean[i]});
        else
            bad = push_fail(x, qg[i], p,
                            isfinite(kth[i]) ? (float)(kth[i] * (1 + 1e-6) + 2 * slack)
                                             : (float)(2 * ((double)x->gr.b * x->gr.cell + tp->m)));
        if (bad) {
            rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
            goto out;
        }
    }
    rc = 0;
out:
    free(q), free(mean), free(kth), free(qg);
    return rc;
}

/* One pass: the points of tiles [t0, t1) and of their margins, into tp[t - t0]. */
static int gather(ctx *x, tpts *tp, size_t t0, size_t t1, double mmax, rs_err *err)
{
    const grid *gr = &x->gr;
    double T = (double)gr->b * gr->cell;
    size_t g = 0;
    int r;
    long c[3];
    rs_ingest_source_rewind(x->s);
    while ((r = rs_ingest_source_next(x->s, err)) > 0)
        for (size_t i = 0; i < x->s->n; i++, g++) {
            if (is_dropped(x->co, g)) continue;
            const double *p = x->s->xyz + 3 * i;
            cell_of(gr, p, c);
            long ot[3] = {c[0] / gr->b, c[1] / gr->b, c[2] / gr->b}, lo[3], hi[3];
            size_t own = tile_index(gr, ot);
            if (own >= t0 && own < t1 && tpts_push(&tp[own - t0], p, (uint32_t)g) != 0) goto nomem;
            if (mmax <= 0) continue;
            for (int j = 0; j < 3; j++) {
                lo[j] = (long)floor((p[j] - mmax - gr->origin[j]) / T) - 1;
                hi[j] = (long)floor((p[j] + mmax - gr->origin[j]) / T);
                lo[j] = lo[j] < 0 ? 0 : lo[j];
                hi[j] = hi[j] >= gr->tdim[j] ? gr->tdim[j] - 1 : hi[j];
            }
            if (lo[0] > hi[0] || lo[1] > hi[1] || lo[2] > hi[2] || tile_index(gr, hi) < t0 || tile_index(gr, lo) >= t1)
                continue;
            long t[3];
            for (t[2] = lo[2]; t[2] <= hi[2]; t[2]++)
                for (t[1] = lo[1]; t[1] <= hi[1]; t[1]++)
                    for (t[0] = lo[0]; t[0] <= hi[0]; t[0]++) {
                        size_t ti = tile_index(gr, t);
                        if (ti < t0 || ti >= t1 || ti == own || gr->tcount[ti] == 0) continue;
                        tpts *q = &tp[ti - t0];
                        int in = 1;
                        for (int j = 0; j < 3; j++) in &= p[j] >= q->lo[j] - q->m && p[j] <= q->hi[j] + q->m;
                        if (in && tpts_push(q, p, UINT32_MAX) != 0) goto nomem;
                    }
        }
    return r < 0 ? -1 : 0;
nomem:
    return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for a batch of tiles");
}

/* The next batch: tiles from t0 on while their points fit four tiles' budget. */
static size_t batch_end(const grid *gr, size_t t0)
{
    size_t load = 0, t = t0;
    for (; t < ntiles(gr); t++) {
        if (load > 0 && load + gr->tcount[t] > 4 * tile_budget()) break;
        load += gr->tcount[t];
    }
    return t;
}

static void tiles_free(tpts *tp, size_t n)
{
    for (size_t i = 0; i < n; i++) free(tp[i].xyz), free(tp[i].g);
    free(tp);
}

/* Every point's mean neighbour distance, into runs (the margins' misses into x->fail_*). */
static int knn_batches(ctx *x, rs_err *err)
{
    grid *gr = &x->gr;
    double T = (double)gr->b * gr->cell;
    size_t nb = 0;
    for (size_t t0 = 0; t0 < ntiles(gr); t0 = batch_end(gr, t0)) nb++;
    rs_progress *pr = nb > 1 ? rs_progress_start("outlier removal (a pass per batch of tiles)", nb) : NULL;
    int rc = 0;
    for (size_t t0 = 0, t1; t0 < ntiles(gr) && rc == 0; t0 = t1) {
        t1 = batch_end(gr, t0);
        tpts *tp = calloc(t1 - t0, sizeof *tp);
        if (!tp) {
            rc = rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
            break;
        }
        double mmax = 0;
        for (size_t t = t0; t < t1; t++) {
            tile_box(gr, t, tp[t - t0].lo, tp[t - t0].hi);
            /* a few point spacings, whether the points fill the tile or lie on a surface in it */
            double n = (double)gr->tcount[t];
            tp[t - t0].m = n > 0 ? fmin(T, 2 * T * cbrt(gr->k / n)) : 0;
            mmax = fmax(mmax, tp[t - t0].m);
        }
        rc = gather(x, tp, t0, t1, mmax, err);
        for (size_t t = t0; t < t1 && rc == 0; t++)
            if (tp[t - t0].own) rc = tile_knn(x, &tp[t - t0], err);
        tiles_free(tp, t1 - t0);
        if (rc == 0) rc = flush_run(x, err);
        if (pr) rs_progress_add(pr, 1);
    }
    if (pr) rs_progress_end(pr);
    return rc;
}

/* The cells of the box p +- radius (and one more each way: a voxel cell's edge is rounded). */
static void box_cells(const grid *gr, const float *p, double radius, long lo[3], long hi[3])
{
    for (int j = 0; j < 3; j++) {
        double a = floor((p[j] - radius - gr->origin[j]) / gr->cell) - 1,
               b = floor((p[j] + radius - gr->origin[j]) / gr->cell) + 1;
        lo[j] = a < 0 ? 0 : a >= (double)gr->dim[j] ? gr->dim[j] - 1 : (long)a;
        hi[j] = b < 0 ? 0 : b >= (double)gr->dim[j] ? gr->dim[j] - 1 : (long)b;
    }
}

/* One fallback round: the first points of the list whose boxes' cells fit a batch, from every
 * point in those cells; the settled ones leave the list, the others get the radius their kth
 * neighbour found needs (or four times theirs when fewer than k points were there). */
static int fallback_round(ctx *x, uint8_t *mark, size_t ncells, rs_err *err)
{
    grid *gr = &x->gr;
    size_t load = 0, ng = 0, g = 0;
    long lo[3], hi[3], c[3];
    memset(mark, 0, ncells);
    for (; ng < x->nfail; ng++) {
        box_cells(gr, x->fail_p + 3 * ng, x->fail_r[ng].d, lo, hi);
        size_t sum = 0;
        for (long z = lo[2]; z <= hi[2]; z++)
            for (long y = lo[1]; y <= hi[1]; y++)
                for (long xx = lo[0]; xx <= hi[0]; xx++)
                    sum += gr->count[(size_t)((z * gr->dim[1] + y) * gr->dim[0] + xx)];
        if (ng > 0 && load + sum > 4 * tile_budget()) break;
        load += sum;
        for (long z = lo[2]; z <= hi[2]; z++)
            for (long y = lo[1]; y <= hi[1]; y++)
                for (long xx = lo[0]; xx <= hi[0]; xx++) mark[(size_t)((z * gr->dim[1] + y) * gr->dim[0] + xx)] = 1;
    }
    tpts all = {0};
    float *mean = malloc(ng * sizeof *mean), *kth = malloc(ng * sizeof *kth);
    int r, rc = -1;
    if (!mean || !kth) goto nomem;
    rs_ingest_source_rewind(x->s);
    while ((r = rs_ingest_source_next(x->s, err)) > 0)
        for (size_t i = 0; i < x->s->n; i++, g++)
            if (!is_dropped(x->co, g) && mark[cell_of(gr, x->s->xyz + 3 * i, c)] &&
                tpts_push(&all, x->s->xyz + 3 * i, 0) != 0)
                goto nomem;
    if (r < 0) goto out;
    if (rs_pcl_knn_mean(all.xyz, all.n, x->fail_p, ng, gr->k, mean, kth, err) != 0) goto out;
    size_t keep = 0;
    for (size_t i = 0; i < x->nfail; i++) {
        const float *p = x->fail_p + 3 * i;
        double slack = slack_of(p);
        if (i < ng && kth[i] <= x->fail_r[i].d - slack) {
            if (push_rec(&x->out, &x->nout, &x->cap_out, (rec){x->fail_r[i].g, mean[i]}) != 0) goto nomem;
            continue;
        }
        rec f = x->fail_r[i];
        if (i < ng) f.d = isfinite(kth[i]) ? (float)(kth[i] * (1 + 1e-6) + 2 * slack) : 4 * f.d;
        memmove(x->fail_p + 3 * keep, p, 3 * sizeof *p);
        x->fail_r[keep++] = f;
    }
    x->nfail = keep;
    rc = flush_run(x, err);
    goto out;
nomem:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the points far from their tile's neighbours");
out:
    free(all.xyz), free(all.g), free(mean), free(kth);
    return rc;
}

static int fallback(ctx *x, size_t *rounds, rs_err *err)
{
    size_t ncells = (size_t)(x->gr.dim[0] * x->gr.dim[1] * x->gr.dim[2]);
    uint8_t *mark = malloc(ncells);
    if (!mark) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    int rc = 0;
    for (*rounds = 0; x->nfail > 0 && rc == 0; ++*rounds) rc = fallback_round(x, mark, ncells, err);
    free(mark);
    return rc;
}

/* The runs merged back into the streamed points' order (a heap of the runs' heads). */
#define RUN_BUF 4096
typedef struct merge {
    ctx *x;
    rec *buf;                 /* RUN_BUF a run */
    size_t *at, *have, *done; /* a run's place in its buffer, the buffer's records, records read */
    size_t *heap, nheap;
} merge;

static int run_fill(merge *m, size_t r)
{
    size_t left = m->x->run_n[r] - m->done[r], n = left < RUN_BUF ? left : RUN_BUF;
    long off = m->x->run_off[r] + (long)(m->done[r] * sizeof(rec));
    ssize_t got = pread(fileno(m->x->tmp), m->buf + r * RUN_BUF, n * sizeof(rec), off);
    if (got != (ssize_t)(n * sizeof(rec))) return -1;
    m->at[r] = 0, m->have[r] = n, m->done[r] += n;
    return 0;
}

static uint32_t head(const merge *m, size_t r)
{
    return m->buf[r * RUN_BUF + m->at[r]].g;
}

static void sift(merge *m, size_t i)
{
    for (;;) {
        size_t l = 2 * i + 1, s = i;
        if (l < m->nheap && head(m, m->heap[l]) < head(m, m->heap[s])) s = l;
        if (l + 1 < m->nheap && head(m, m->heap[l + 1]) < head(m, m->heap[s])) s = l + 1;
        if (s == i) return;
        size_t t = m->heap[i];
        m->heap[i] = m->heap[s], m->heap[s] = t, i = s;
    }
}

static int merge_open(merge *m, ctx *x, rs_err *err)
{
    memset(m, 0, sizeof *m);
    m->x = x;
    size_t n = x->nruns ? x->nruns : 1;
    m->buf = malloc(n * RUN_BUF * sizeof *m->buf);
    m->at = calloc(n, sizeof *m->at), m->have = calloc(n, sizeof *m->have), m->done = calloc(n, sizeof *m->done);
    m->heap = calloc(n, sizeof *m->heap);
    if (!m->buf || !m->at || !m->have || !m->done || !m->heap)
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    if (fflush(x->tmp) != 0) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "cannot write a temporary file");
    for (size_t r = 0; r < x->nruns; r++) {
        if (run_fill(m, r) != 0) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "cannot read a temporary file");
        if (m->have[r]) m->heap[m->nheap++] = r;
    }
    for (size_t i = m->nheap; i-- > 0;) sift(m, i);
    return 0;
}

/* 1 and the next record, 0 at the end, -1 on a read error. */
static int merge_next(merge *m, rec *out)
{
    if (m->nheap == 0) return 0;
    size_t r = m->heap[0];
    *out = m->buf[r * RUN_BUF + m->at[r]++];
    if (m->at[r] == m->have[r]) {
        if (m->done[r] < m->x->run_n[r]) {
            if (run_fill(m, r) != 0) return -1;
        } else {
            m->heap[0] = m->heap[--m->nheap];
        }
    }
    sift(m, 0);
    return 1;
}

static void merge_close(merge *m)
{
    free(m->buf), free(m->at), free(m->have), free(m->done), free(m->heap);
}

/* PCL's threshold from the distances in the files' order (its summation order), then the
 * outliers marked dropped. */
static int mark_outliers(ctx *x, size_t *removed, rs_err *err)
{
    double sum = 0, sq_sum = 0, thr = 0;
    size_t valid = 0;
    *removed = 0;
    for (int pass = 0; pass < 2; pass++) {
        merge m;
        rec e;
        int r;
        if (merge_open(&m, x, err) != 0) {
            merge_close(&m);
            return -1;
        }
        while ((r = merge_next(&m, &e)) > 0) {
            if (pass == 0) {
                float d2 = e.d * e.d; /* PCL: distance * distance, in float */
                sum += e.d, sq_sum += d2, valid++;
            } else if (e.d > thr) {
                x->co->dropped[e.g >> 3] |= (uint8_t)(1u << (e.g & 7));
                ++*removed;
            }
        }
        merge_close(&m);
        if (r < 0) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "cannot read a temporary file");
        if (pass == 0 && valid != x->co->distinct)
            return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0,
                              "the tiles gave %zu neighbour distances for %zu points (an internal error)", valid,
                              x->co->distinct);
        double mean = sum / (double)valid;
        double variance = (sq_sum - sum * sum / (double)valid) / ((double)valid - 1);
        thr = mean + rs_config_real(x->cfg, "ingest", "outlier_std") * sqrt(variance);
    }
    return 0;
}

/* A voxel centroid, as the temporary file holds it. */
typedef struct vrec {
    float xyz[3], in;
    uint8_t rgb[3];
} vrec;

typedef struct vpts {
    float *xyz, *in;
    uint8_t *rgb;
    size_t n, cap;
} vpts;

static int vpts_push(vpts *v, const source *s, size_t i)
{
    if (v->n == v->cap) {
        size_t cap = v->cap ? 2 * v->cap : 1024;
        float *xyz = realloc(v->xyz, 3 * cap * sizeof *xyz);
        if (xyz) v->xyz = xyz;
        float *in = realloc(v->in, cap * sizeof *in);
        if (in) v->in = in;
        uint8_t *rgb = realloc(v->rgb, 3 * cap);
        if (rgb) v->rgb = rgb;
        if (!xyz || !in || !rgb) return -1;
        v->cap = cap;
    }
    for (int j = 0; j < 3; j++)
        v->xyz[3 * v->n + j] = (float)s->xyz[3 * i + j], v->rgb[3 * v->n + j] = s->rgb[3 * i + j];
    v->in[v->n++] = s->in[i];
    return 0;
}

/* One tile's survivors through PCL's voxel grid, the centroids appended to vt. */
static int voxel_tile(ctx *x, const vpts *v, FILE *vt, size_t *nout, rs_err *err)
{
    size_t m = 0;
    float *ox = NULL, *oi = NULL;
    uint8_t *orgb = NULL;
    int rc = rs_pcl_voxel(v->xyz, x->s->has_int ? v->in : NULL, x->s->has_rgb ? v->rgb : NULL, v->n, x->gr.leaf, &m,
                          &ox, &oi, &orgb, err);
    for (size_t i = 0; i < m && rc == 0; i++) {
        vrec r = {{ox[3 * i], ox[3 * i + 1], ox[3 * i + 2]}, oi ? oi[i] : 0, {0, 0, 0}};
        if (orgb) memcpy(r.rgb, orgb + 3 * i, 3);
        if (fwrite(&r, sizeof r, 1, vt) != 1)
            rc = rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "cannot write the voxels' temporary file (disk full?)");
    }
    *nout += m;
    free(ox), free(oi), free(orgb);
    return rc;
}

/* The voxel grid, a batch of tiles a pass: each tile's surviving points, then its voxels. */
static int voxel_batches(ctx *x, FILE *vt, size_t *nin, size_t *nout, rs_err *err)
{
    grid *gr = &x->gr;
    size_t nb = 0;
    for (size_t t0 = 0; t0 < ntiles(gr); t0 = batch_end(gr, t0)) nb++;
    rs_progress *pr = nb > 1 ? rs_progress_start("voxel grid (a pass per batch of tiles)", nb) : NULL;
    int rc = 0;
    *nin = *nout = 0;
    for (size_t t0 = 0, t1; t0 < ntiles(gr) && rc == 0; t0 = t1) {
        t1 = batch_end(gr, t0);
        vpts *v = calloc(t1 - t0, sizeof *v);
        if (!v) {
            rc = rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
            break;
        }
        size_t g = 0;
        int r;
        long c[3];
        rs_ingest_source_rewind(x->s);
        while (rc == 0 && (r = rs_ingest_source_next(x->s, err)) > 0)
            for (size_t i = 0; i < x->s->n && rc == 0; i++, g++) {
                if (is_dropped(x->co, g)) continue;
                cell_of(gr, x->s->xyz + 3 * i, c);
                long ot[3] = {c[0] / gr->b, c[1] / gr->b, c[2] / gr->b};
                size_t t = tile_index(gr, ot);
                if (t >= t0 && t < t1 && vpts_push(&v[t - t0], x->s, i) != 0)
                    rc = rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for a batch of tiles");
            }
        if (rc == 0 && r < 0) rc = -1;
        for (size_t t = t0; t < t1 && rc == 0; t++)
            if (v[t - t0].n) {
                *nin += v[t - t0].n;
                rc = voxel_tile(x, &v[t - t0], vt, nout, err);
            }
        for (size_t t = t0; t < t1; t++) free(v[t - t0].xyz), free(v[t - t0].in), free(v[t - t0].rgb);
        free(v);
        if (pr) rs_progress_add(pr, 1);
    }
    if (pr) rs_progress_end(pr);
    return rc;
}

typedef struct vreader {
    FILE *f;
    const source *s;
} vreader;

static int voxel_record(void *ctx_, const rs_ply_element *el, size_t k, double *v, rs_err *err)
{
    (void)el, (void)k;
    vreader *rd = ctx_;
    vrec r;
    if (fread(&r, sizeof r, 1, rd->f) != 1)
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "cannot read a temporary file");
    int n = 0;
    for (int j = 0; j < 3; j++) v[n++] = r.xyz[j];
    if (rd->s->has_int) v[n++] = r.in;
    if (rd->s->has_rgb)
        for (int j = 0; j < 3; j++) v[n++] = r.rgb[j];
    return 0;
}

/* The voxel grid's half of the cleaning, and cloud.ply from its centroids. */
static int voxel_and_write(ctx *x, rs_report *rep, rs_cloud *shape, const char *path, char *tmp_path, rs_err *err)
{
    double t0 = rs_now();
    size_t nin = 0, nout = 0;
    strcat(tmp_path, "v");
    FILE *vt = fopen(tmp_path, "w+b");
    if (!vt) return rs_err_set(err, RS_ERR_SYSTEM, tmp_path, 0, "cannot create a temporary file");
    unlink(tmp_path);
    int rc = voxel_batches(x, vt, &nin, &nout, err);
    if (rc == 0) {
        if (shape->normal) {
            shape->normal = NULL; /* a centroid has no normal of the file's */
            x->s->has_nrm = 0;
            rs_log_info("voxel downsampling: the file's normals are not carried (the mesh stage estimates them)");
        }
        rs_report_time(rep, "voxel", rs_now() - t0);
        rs_log_info("voxel downsampling (%g m): %zu -> %zu unorganized points (%zu tiles of %ld voxels a side)",
                    x->gr.leaf, nin, nout, ntiles(&x->gr), x->gr.b * x->gr.vcell);
        rs_json_set_num(rep->metrics, "voxel_size_m", x->gr.leaf);
        rs_json_set_int(rep->metrics, "voxel_points_in", (long long)nin);
        rs_json_set_int(rep->metrics, "voxel_points_out", (long long)nout);
        rs_json_set_int(rep->metrics, "points_written", (long long)nout);
        t0 = rs_now();
        rewind(vt);
        vreader rd = {vt, x->s};
        rc = rs_cloud_write_ply_stream(shape, nout, voxel_record, &rd, path, err);
        if (rc == 0) rs_report_time(rep, "write", rs_now() - t0);
    }
    fclose(vt);
    return rc;
}

/* Statistical outlier removal over the tiles: distances, the fallback, the threshold. */
static int outliers(ctx *x, rs_report *rep, size_t *removed, rs_err *err)
{
    double t0 = rs_now();
    size_t rounds = 0, missed;
    if (knn_batches(x, err) != 0) return -1;
    missed = x->nfail;
    if (fallback(x, &rounds, err) != 0 || mark_outliers(x, removed, err) != 0) return -1;
    rs_report_time(rep, "outliers", rs_now() - t0);
    rs_log_info("statistical outlier removal (%d neighbours, %g sigma): %zu of %zu unorganized points removed (%zu "
                "tiles, %zu of the points beyond their tile's margin, settled in %zu more pass%s)",
                x->gr.k, rs_config_real(x->cfg, "ingest", "outlier_std"), *removed, x->co->distinct, ntiles(&x->gr),
                missed, rounds, rounds == 1 ? "" : "es");
    rs_json_set_int(rep->metrics, "tiles", (long long)ntiles(&x->gr));
    rs_json_set_int(rep->metrics, "tile_margin_missed", (long long)missed);
    return 0;
}

int rs_ingest_clean_stream(const rs_config *cfg, source *s, rs_report *rep, coincident *co, rs_cloud *shape,
                           const double lo[3], const double hi[3], const char *path, rs_err *err)
{
    ctx x = {.cfg = cfg, .s = s, .co = co};
    long k = rs_config_int(cfg, "ingest", "outlier_neighbours");
    char tmp_path[4200];
    size_t removed = 0;
    int rc = -1;
    if (co->total >= UINT32_MAX)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "%zu unorganized points: at most %u are supported", co->total,
                          UINT32_MAX - 1);
    if (rs_config_has(cfg, "ingest", "voxel_size")) {
        double far = 0, leaf = rs_config_real(cfg, "ingest", "voxel_size");
        for (int j = 0; j < 3; j++) far = fmax(far, fmax(fabs(lo[j]), fabs(hi[j])));
        if (!(far / leaf < 1e15)) /* voxel indices beyond a long (and beyond PCL's float grid) */
            return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                              "voxel size %g m for coordinates up to %.4g m: expected a larger voxel size", leaf, far);
    }
    grid_setup(&x.gr, cfg, lo, hi);
    x.gr.k = k > 0 && co->distinct > (size_t)k ? (int)k : 0;
    snprintf(tmp_path, sizeof tmp_path, "%s.tiles.tmp", path);
    x.tmp = fopen(tmp_path, "w+b");
    if (!x.tmp) return rs_err_set(err, RS_ERR_SYSTEM, tmp_path, 0, "cannot create a temporary file");
    unlink(tmp_path); /* gone when closed, whatever happens */
    s->xyz_only = 1;
    if (count_cells(&x, err) != 0) goto out;
    if (x.gr.k > 0) {
        if (outliers(&x, rep, &removed, err) != 0) goto out;
    } else {
        rs_report_skip(rep, "outlier removal",
                       k > 0 ? "too few unorganized points" : "[ingest] outlier_neighbours = 0");
    }
    rs_json_set_int(rep->metrics, "outliers_removed", (long long)removed);
    s->xyz_only = 0;
    if (x.gr.voxel) {
        rc = voxel_and_write(&x, rep, shape, path, tmp_path, err);
        goto out;
    }
    rs_report_skip(rep, "voxel downsampling", "[ingest] voxel_size not set");
    rs_json_set_int(rep->metrics, "points_written", (long long)(co->distinct - removed));
    double t0 = rs_now();
    if (rs_ingest_write_points(s, co, shape, co->distinct - removed, path, err) != 0) goto out;
    rs_report_time(rep, "write", rs_now() - t0);
    rs_log_info("cloud.ply: %zu points written from the files' chunks (streaming, cleaned in tiles)",
                co->distinct - removed);
    rc = 0;
out:
    fclose(x.tmp);
    free(x.gr.count), free(x.gr.tcount), free(x.run_off), free(x.run_n), free(x.out), free(x.fail_r), free(x.fail_p);
    return rc;
}

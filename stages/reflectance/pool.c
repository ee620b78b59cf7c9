/* pool: neighbour lists for irradiance shared within a plane (see pool.h). The facets'
 * centroids go into a hashed uniform grid whose cell is the median search radius, so that a
 * typical search visits 27 cells. */
#include "stages/reflectance/pool.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/select.h"

typedef struct {
    const uint8_t *wanted; /* facets that search (NULL: all) */
    double a, h;           /* accuracy, cell size */
    rs_v3 lo;
    rs_v3 *c, *n;
    double *area, *R, *radius; /* R: harmonic mean distance (INFINITY: sees no facet) */
    int32_t *cell;             /* 3 per facet */
    size_t *bucket_start, mask;
    uint32_t *members; /* facets sorted by bucket */
} grid;

typedef struct {
    uint32_t j;
    double eps, w;
} cand;

static size_t cell_hash(const int32_t *k, size_t mask)
{
    uint64_t h = (uint64_t)(uint32_t)k[0] * 73856093u ^ (uint64_t)(uint32_t)k[1] * 19349663u ^
        (uint64_t)(uint32_t)k[2] * 83492791u;
    h ^= h >> 29;
    return (size_t)(h * 0xbf58476d1ce4e5b9ULL >> 17) & mask;
}

static int32_t cell_of(double x, double lo, double h)
{
    return (int32_t)floor((x - lo) / h);
}

static int by_eps(const void *a, const void *b)
{
    const cand *x = a, *y = b;
    if (x->eps != y->eps) return x->eps < y->eps ? -1 : 1;
    return (x->j > y->j) - (x->j < y->j);
}

/* Appends j to i's candidates when Ward's test and the plane test pass. -1: out of memory. */
static int try_candidate(const grid *g, uint32_t i, uint32_t j, cand **buf, size_t *cap, size_t *nc)
{
    rs_v3 d = rs_v3_sub(g->c[j], g->c[i]);
    double dist = rs_v3_len(d), nn = rs_v3_dot(g->n[i], g->n[j]);
    if (dist > g->radius[i] || nn <= 0 || fabs(rs_v3_dot(g->n[i], d)) > g->a * dist) return 0;
    double eps = dist / fmin(g->R[i], g->R[j]) + sqrt(fmax(0, 1 - nn));
    if (!(eps < g->a)) return 0;
    if (*nc == *cap) {
        size_t nb = *cap ? 2 * *cap : 64;
        cand *t = realloc(*buf, nb * sizeof *t);
        if (!t) return -1;
        *buf = t, *cap = nb;
    }
    (*buf)[*nc].j = j, (*buf)[*nc].eps = eps, (*buf)[*nc].w = g->area[j] * (1 - eps / g->a);
    (*nc)++;
    return 0;
}

/* Facet i's neighbours (itself first) into out[] (room for RS_POOL_MAX_NEIGHBOURS); returns
 * how many, 0 when out of memory. buf: scratch that grows. */
static size_t neighbours(const grid *g, uint32_t i, cand **buf, size_t *cap, cand *out)
{
    out[0].j = i, out[0].eps = 0, out[0].w = g->area[i];
    double r = g->radius[i];
    if (!(r > 0) || !g->h || (g->wanted && !g->wanted[i])) return 1;
    size_t nc = 0;
    int32_t k0[3], k1[3];
    const double ci[3] = {g->c[i].x, g->c[i].y, g->c[i].z}, lo[3] = {g->lo.x, g->lo.y, g->lo.z};
    for (int d = 0; d < 3; d++) {
        k0[d] = cell_of(ci[d] - r, lo[d], g->h);
        k1[d] = cell_of(ci[d] + r, lo[d], g->h);
    }
    /* A facet far larger than the median searches every member rather than more cells than
     * there are facets (a coarse ground triangle among a fine wall's). */
    double cells = 1;
    for (int d = 0; d < 3; d++) cells *= (double)k1[d] - k0[d] + 1;
    int all = cells > (double)g->bucket_start[g->mask + 1];
    int32_t k[3];
    for (k[0] = k0[0]; k[0] <= k1[0]; k[0]++)
        for (k[1] = k0[1]; k[1] <= k1[1]; k[1]++)
            for (k[2] = k0[2]; k[2] <= k1[2]; k[2]++) {
                size_t b = cell_hash(k, g->mask), q0 = all ? 0 : g->bucket_start[b],
                       q1 = all ? g->bucket_start[g->mask + 1] : g->bucket_start[b + 1];
                for (size_t q = q0; q < q1; q++) {
                    uint32_t j = g->members[q];
                    const int32_t *kj = g->cell + 3 * (size_t)j;
                    if (j == i || (!all && (kj[0] != k[0] || kj[1] != k[1] || kj[2] != k[2]))) continue;
                    if (try_candidate(g, i, j, buf, cap, &nc) != 0) return 0; /* out of memory */
                }
                if (all) goto searched;
            }
searched:
    if (!nc) return 1; /* none: buf may not exist yet (qsort and memcpy take no NULL) */
    /* The order of the buckets must not decide which neighbours are kept, nor the sums. */
    qsort(*buf, nc, sizeof **buf, by_eps);
    if (nc > RS_POOL_MAX_NEIGHBOURS - 1) nc = RS_POOL_MAX_NEIGHBOURS - 1;
    memcpy(out + 1, *buf, nc * sizeof *out);
    return nc + 1;
}

static int grid_build(grid *g, size_t nf)
{
    float *radii = malloc((nf ? nf : 1) * sizeof *radii);
    if (!radii) return -1;
    size_t nr = 0;
    g->lo = rs_v3_make(INFINITY, INFINITY, INFINITY);
    for (size_t f = 0; f < nf; f++) {
        if (!(g->radius[f] > 0)) continue;
        radii[nr++] = (float)g->radius[f];
        g->lo = rs_v3_make(fmin(g->lo.x, g->c[f].x), fmin(g->lo.y, g->c[f].y), fmin(g->lo.z, g->c[f].z));
    }
    g->h = nr ? rs_select_kth(radii, nr, nr / 2) : 0;
    free(radii);
    if (!(g->h > 0)) {
        g->h = 0;
        return 0;
    }
    size_t nb = 1;
    while (nb < 2 * nr) nb *= 2;
    g->mask = nb - 1;
    g->bucket_start = calloc(nb + 1, sizeof *g->bucket_start);
    g->members = malloc(nr * sizeof *g->members);
    size_t *fill = malloc((nb + 1) * sizeof *fill);
    if (!g->bucket_start || !g->members || !fill) {
        free(fill);
        return -1;
    }
    const double lo[3] = {g->lo.x, g->lo.y, g->lo.z};
    for (size_t f = 0; f < nf; f++) {
        if (!(g->radius[f] > 0)) continue;
        const double c[3] = {g->c[f].x, g->c[f].y, g->c[f].z};
        for (int d = 0; d < 3; d++) g->cell[3 * f + d] = cell_of(c[d], lo[d], g->h);
        g->bucket_start[cell_hash(g->cell + 3 * f, g->mask) + 1]++;
    }
    for (size_t b = 0; b < nb; b++) g->bucket_start[b + 1] += g->bucket_start[b];
    memcpy(fill, g->bucket_start, (nb + 1) * sizeof *fill);
    for (size_t f = 0; f < nf; f++)
        if (g->radius[f] > 0) g->members[fill[cell_hash(g->cell + 3 * f, g->mask)]++] = (uint32_t)f;
    free(fill);
    return 0;
}

int rs_pool_build(const rs_mesh *mesh, const double *inv_dist, const uint8_t *usable, const uint8_t *wanted,
                  double accuracy, rs_pool *p)
{
    size_t nf = mesh->nfaces;
    memset(p, 0, sizeof *p);
    p->nf = nf;
    grid g = {.wanted = wanted, .a = accuracy};
    g.c = malloc((nf + 1) * sizeof *g.c);
    g.n = malloc((nf + 1) * sizeof *g.n);
    g.area = malloc((nf + 1) * sizeof *g.area);
    g.R = malloc((nf + 1) * sizeof *g.R);
    g.radius = malloc((nf + 1) * sizeof *g.radius);
    g.cell = malloc(3 * (nf + 1) * sizeof *g.cell);
    p->start = malloc((nf + 1) * sizeof *p->start);
    int rc = -1;
    if (!g.c || !g.n || !g.area || !g.R || !g.radius || !g.cell || !p->start) goto out;
    for (size_t f = 0; f < nf; f++) {
        rs_mesh_face(mesh, f, &g.c[f], &g.n[f], &g.area[f]);
        g.R[f] = inv_dist[f] > 0 ? 1 / inv_dist[f] : INFINITY;
        int ok = accuracy > 0 && rs_v3_len(g.n[f]) > 0 && g.area[f] > 0 && (!usable || usable[f]);
        g.radius[f] = ok ? fmin(accuracy * g.R[f], sqrt(RS_POOL_FACETS * g.area[f] / M_PI)) : 0;
    }
    if (grid_build(&g, nf) != 0) goto out;

    /* Twice: the counts, then the lists into the one array they size. */
    int failed = 0;
    p->start[0] = 0;
    for (int pass = 0; pass < 2; pass++) {
        if (pass) {
            for (size_t f = 0; f < nf; f++) p->start[f + 1] += p->start[f];
            p->nbr = malloc((p->start[nf] + 1) * sizeof *p->nbr);
            p->w = malloc((p->start[nf] + 1) * sizeof *p->w);
            if (!p->nbr || !p->w) goto out;
        }
#pragma omp parallel reduction(|| : failed)
        {
            cand *buf = NULL, *out = malloc(RS_POOL_MAX_NEIGHBOURS * sizeof *out);
            size_t cap = 0;
            if (!out) failed = 1;
#pragma omp for schedule(dynamic, 256)
            for (size_t f = 0; f < nf; f++) {
                if (!out) continue;
                size_t k = neighbours(&g, (uint32_t)f, &buf, &cap, out);
                if (!k) {
                    failed = 1;
                    continue;
                }
                if (!pass) {
                    p->start[f + 1] = k;
                    continue;
                }
                double sum = 0;
                for (size_t q = 0; q < k; q++) sum += out[q].w;
                for (size_t q = 0; q < k; q++) {
                    p->nbr[p->start[f] + q] = out[q].j;
                    p->w[p->start[f] + q] = (float)(sum > 0 ? out[q].w / sum : (q == 0));
                }
            }
            free(buf);
            free(out);
        }
        if (failed) goto out;
    }
    rc = 0;
out:
    free(g.c);
    free(g.n);
    free(g.area);
    free(g.R);
    free(g.radius);
    free(g.cell);
    free(g.bucket_start);
    free(g.members);
    if (rc != 0) rs_pool_free(p);
    return rc;
}

void rs_pool_free(rs_pool *p)
{
    free(p->start);
    free(p->nbr);
    free(p->w);
    memset(p, 0, sizeof *p);
}

void rs_pool_apply3(const rs_pool *p, const double *v, double *out)
{
#pragma omp parallel for schedule(static)
    for (size_t i = 0; i < p->nf; i++) {
        double s[3] = {0, 0, 0};
        for (size_t q = p->start[i]; q < p->start[i + 1]; q++)
            for (int ch = 0; ch < 3; ch++) s[ch] += p->w[q] * v[3 * (size_t)p->nbr[q] + ch];
        for (int ch = 0; ch < 3; ch++) out[3 * i + ch] = s[ch];
    }
}

void rs_pool_sigma(const rs_pool *p, const double *sigma, double *out)
{
#pragma omp parallel for schedule(static)
    for (size_t i = 0; i < p->nf; i++) {
        double s = 0;
        for (size_t q = p->start[i]; q < p->start[i + 1]; q++) {
            double t = p->w[q] * sigma[p->nbr[q]];
            s += t * t;
        }
        out[i] = sqrt(s);
    }
}

void rs_pool_stats(const rs_pool *p, const uint8_t *wanted, double *mean_count, size_t *pooled, size_t *asked_out)
{
    size_t n = 0, asked = 0, entries = 0;
    for (size_t i = 0; i < p->nf; i++) {
        if (wanted && !wanted[i]) continue;
        size_t k = p->start[i + 1] - p->start[i];
        asked++;
        entries += k;
        n += k > 1;
    }
    *pooled = n;
    *asked_out = asked;
    *mean_count = asked ? (double)entries / asked : 0;
}

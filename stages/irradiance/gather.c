/* gather: hemisphere gather per facet (see gather.h and irradiance.c). Cosine-weighted
 * Owen-scrambled Sobol directions from Sobol points spread over the facet; explicit shadow rays
 * toward the sky map's bright pixels, chosen by power. */
#include "gather.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "log.h"
#include "sampling.h"
#include "skysh.h"

typedef struct {
    uint32_t face;
    uint8_t unseen;            /* the radiance at the hit point was not read from the panorama */
} hit_ref;

/* Search guide of one sky distribution (Chen's indexed search): guide[b] is the first pixel k
 * with cdf[k + 1] > b / GUIDE_BUCKETS of the total, so that a pick searches only between
 * guide[b] and guide[b + 1] and gives the same pixel as a binary search over the whole map,
 * without its cache misses (the profile's top entry: 58 % of the gather at 1024 x 512). */
enum { GUIDE_BUCKETS = 1 << 18 };
typedef struct {
    const double *cdf;         /* the distribution it was built for (NULL: not built) */
    uint32_t guide[GUIDE_BUCKETS + 1];
} sky_guide;

struct rs_gather_scratch {
    sky_guide sky, sun;        /* cached on first use: a scratch serves one sky map for its life */
    const rs_mesh *box_mesh;   /* the mesh whose bounding box lo/hi holds (NULL: not computed) */
    float lo[3], hi[3];
    rs_ray *rays;
    rs_hit *hits;
    hit_ref *refs;
    uint32_t *pixels;          /* sky pixel of each map-sampled ray */
    double *samp;              /* 5 per ray: the Sobol coordinates of a map-sampled ray */
    uint32_t *range_lo, *range_hi; /* per ray: the guide's search range */
    uint8_t *occl;
};

rs_gather_scratch *rs_gather_scratch_new(size_t n)
{
    rs_gather_scratch *s = calloc(1, sizeof *s);
    if (!s) return NULL;
    n = n ? n : 1;
    s->rays = malloc(n * sizeof *s->rays);
    s->hits = malloc(n * sizeof *s->hits);
    s->refs = malloc(n * sizeof *s->refs);
    s->pixels = malloc(n * sizeof *s->pixels);
    s->samp = malloc(5 * n * sizeof *s->samp);
    s->range_lo = malloc(n * sizeof *s->range_lo);
    s->range_hi = malloc(n * sizeof *s->range_hi);
    s->occl = malloc(n);
    if (!s->rays || !s->hits || !s->refs || !s->pixels || !s->samp || !s->range_lo || !s->range_hi || !s->occl) {
        rs_gather_scratch_free(s);
        return NULL;
    }
    return s;
}

void rs_gather_scratch_free(rs_gather_scratch *s)
{
    if (!s) return;
    free(s->rays);
    free(s->hits);
    free(s->refs);
    free(s->pixels);
    free(s->samp);
    free(s->range_lo);
    free(s->range_hi);
    free(s->occl);
    free(s);
}

static void guide_build(sky_guide *g, const double *cdf, size_t npx)
{
    double total = cdf[npx];
    size_t k = 0;
    for (size_t b = 0; b <= GUIDE_BUCKETS; b++) {
        double target = (double)b / GUIDE_BUCKETS * total;
        while (k < npx && !(cdf[k + 1] > target)) k++;
        g->guide[b] = (uint32_t)k;
    }
    g->cdf = cdf;
}

/* The pixel rs_skyenv_pick (or _pick_sun) returns for x, found through the guide: the first k
 * with cdf[k + 1] > x * total lies in [guide[b], guide[b + 1]] for b = floor(x * buckets). */
static size_t guide_pick(sky_guide *g, const double *cdf, size_t npx, double x)
{
    if (g->cdf != cdf) guide_build(g, cdf, npx);
    double target = x * cdf[npx];
    size_t b = (size_t)(x * GUIDE_BUCKETS);
    if (b >= GUIDE_BUCKETS) b = GUIDE_BUCKETS - 1;
    size_t lo = g->guide[b], hi = g->guide[b + 1];
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (cdf[mid + 1] > target) hi = mid;
        else lo = mid + 1;
    }
    /* Only a clamped end can land on a pixel without power (elsewhere pixel lo - 1 failed the
     * test, so cdf[lo] <= target < cdf[lo + 1]): walk back as the binary search does. */
    if (lo >= npx) {
        lo = npx - 1;
        while (lo > 0 && cdf[lo + 1] == cdf[lo]) lo--;
    }
    return lo;
}

size_t rs_gather_pick(rs_gather_scratch *s, const rs_skyenv *env, int sun, double x)
{
    size_t npx = (size_t)env->width * env->height;
    return sun ? guide_pick(&s->sun, env->sun_cdf, npx, x) : guide_pick(&s->sky, env->cdf, npx, x);
}

/* 1 when nothing of the model lies above facet f's plane by more than half the ray offset:
 * every ray from f then escapes (origins sit one offset above the plane, directions point away
 * from it), so its rays need not be traced. Tested on the corners of the model's bounding box
 * (conservative and O(1) per facet): it catches the top of the highest roofs, not every
 * convex facet. */
static int sees_nothing(const rs_gather_ctx *g, rs_gather_scratch *s, rs_v3 n, rs_v3 a)
{
    const rs_mesh *m = rs_scene_mesh(g->scene);
    if (s->box_mesh != m) {
        for (int k = 0; k < 3; k++) s->lo[k] = INFINITY, s->hi[k] = -INFINITY;
        for (size_t v = 0; v < m->nverts; v++)
            for (int k = 0; k < 3; k++) {
                s->lo[k] = fminf(s->lo[k], m->verts[3 * v + k]);
                s->hi[k] = fmaxf(s->hi[k], m->verts[3 * v + k]);
            }
        s->box_mesh = m;
    }
    double eps = 0.5 * rs_scene_offset(g->scene, rs_v3_make(0, 0, 0)), top = -INFINITY;
    for (int k = 0; k < 8; k++) {
        rs_v3 corner = rs_v3_make(k & 1 ? s->hi[0] : s->lo[0], k & 2 ? s->hi[1] : s->lo[1], k & 4 ? s->hi[2] : s->lo[2]);
        top = fmax(top, rs_v3_dot(n, rs_v3_sub(corner, a)));
    }
    return top <= eps;
}

/* guide_pick for B values at once, in three sweeps so that the cache misses of different picks
 * overlap instead of queueing (the map's CDF is megabytes, each pick a random place in it):
 * the guide entries, then the first CDF probe of each range, then the searches. */
static void guide_pick_batch(rs_gather_scratch *s, const rs_skyenv *env, int sun, const double *x, int stride, int B)
{
    sky_guide *g = sun ? &s->sun : &s->sky;
    const double *cdf = sun ? env->sun_cdf : env->cdf;
    size_t npx = (size_t)env->width * env->height;
    if (g->cdf != cdf) guide_build(g, cdf, npx);
    for (int i = 0; i < B; i++) {
        size_t b = (size_t)(x[i * stride] * GUIDE_BUCKETS);
        __builtin_prefetch(&g->guide[b < GUIDE_BUCKETS ? b : GUIDE_BUCKETS - 1]);
    }
    for (int i = 0; i < B; i++) {
        size_t b = (size_t)(x[i * stride] * GUIDE_BUCKETS);
        if (b >= GUIDE_BUCKETS) b = GUIDE_BUCKETS - 1;
        s->range_lo[i] = g->guide[b];
        s->range_hi[i] = g->guide[b + 1];
        __builtin_prefetch(&cdf[s->range_lo[i] + (s->range_hi[i] - s->range_lo[i]) / 2 + 1]);
    }
    for (int i = 0; i < B; i++) {
        double target = x[i * stride] * cdf[npx];
        size_t lo = s->range_lo[i], hi = s->range_hi[i];
        while (lo < hi) {
            size_t mid = lo + (hi - lo) / 2;
            if (cdf[mid + 1] > target) hi = mid;
            else lo = mid + 1;
        }
        if (lo >= npx) {                           /* as in guide_pick */
            lo = npx - 1;
            while (lo > 0 && cdf[lo + 1] == cdf[lo]) lo--;
        }
        s->pixels[i] = (uint32_t)lo;
    }
}

static int cmp_hit(const void *a, const void *b)
{
    const hit_ref *x = a, *y = b;
    if (x->face != y->face) return x->face < y->face ? -1 : 1;
    return (int)x->unseen - (int)y->unseen;
}

/* The panorama's radiance at world point x on facet j, when the camera sees x there. */
static int read_seen(const rs_gather_ctx *g, uint32_t j, rs_v3 x, double out[3])
{
    const rs_capture *cap = g->cap;
    if (!cap) return 0;
    int c, r;
    rs_pano_world_to_pixel(&cap->pose, cap->pano->width, cap->pano->height,
                           rs_v3_sub(x, cap->pose.position), &c, &r);
    size_t k = (size_t)r * cap->pano->width + c;
    if (g->facet_id[k] != (float)j) return 0;
    const float *px = cap->pano->data + 3 * k;
    if (!rs_capture_pixel_ok(px)) return 0;
    for (int ch = 0; ch < 3; ch++) out[ch] = px[ch];
    return 1;
}

/* Adds weight * (sky radiance of pixel pix) to E_sky. */
static void add_sky(const rs_skyenv *env, size_t pix, double weight, rs_facet_gather *out)
{
    const float *L = env->radiance + 3 * pix;
    for (int ch = 0; ch < 3; ch++) out->esky[ch] += weight * L[ch];
    double lum = weight * rs_skyenv_luminance(L);
    out->esky_lum += lum;
    if (env->filled[pix]) out->filled_lum += lum;
}

/* Gathers one facet; rays/hits/refs are the thread's scratch (samples entries each). */
int rs_gather_facet(const rs_gather_ctx *g, uint32_t f, rs_gather_scratch *s, rs_facet_gather *out)
{
    rs_ray *rays = s->rays;
    rs_hit *hits = s->hits;
    hit_ref *refs = s->refs;
    uint8_t *occl = s->occl;
    memset(out, 0, sizeof *out);
    const rs_mesh *m = rs_scene_mesh(g->scene);
    rs_v3 n = rs_scene_normal(g->scene, f);
    if (rs_v3_len(n) == 0) return 0;          /* degenerate: no irradiance, not estimable */
    rs_v3 a = rs_mesh_vert(m, m->tris[3 * f]), b = rs_mesh_vert(m, m->tris[3 * f + 1]),
          c = rs_mesh_vert(m, m->tris[3 * f + 2]);
    /* Only sky above the plane and a smooth sky: its harmonic projection, no ray (skysh.h). */
    if (g->sky_sh && g->skip_convex && sees_nothing(g, s, n, a) && rs_skysh_facet(g->sky_sh, n, out)) return 0;
    uint32_t seed = rs_hash_combine(g->seed, f);
    int N = g->samples;
    for (int k = 0; k < N; k++) {
        double x, y, px, py;
        rs_sobol2_owen((uint32_t)k, rs_hash_combine(seed, 1), &x, &y);
        rs_sobol2_owen((uint32_t)k, rs_hash_combine(seed, 2), &px, &py);
        rs_v3 p = rs_triangle_point(a, b, c, px, py);
        rays[k].org = rs_v3_add(p, rs_v3_scale(n, rs_scene_offset(g->scene, p)));
        rays[k].dir = rs_cosine_hemisphere(n, x, y);
        rays[k].tnear = 0;
        rays[k].tfar = INFINITY;
    }
    out->sees_nothing = (uint8_t)(g->skip_convex && sees_nothing(g, s, n, a));
    if (out->sees_nothing)                   /* the answer Embree would give, without asking */
        for (int k = 0; k < N; k++) hits[k].face = RS_NO_HIT;
    else
        rs_scene_intersect(g->scene, rays, hits, (size_t)N);
    const rs_skyenv *env = g->env;
    /* The sky is split in two. The sun set (small, very bright) gets Ns rays of its own, chosen
     * by power. The rest is sampled two ways combined by multiple importance sampling (Veach
     * 1997, balance heuristic): the cosine-weighted rays above and Ne rays drawn from the map's
     * distribution. Cosine rays that land in the sun set count nothing: the sun rays have it. */
    int Nc = N, Ne = env && env->cdf ? g->sky_samples : 0, Ns = env && env->sun_cdf ? g->sun_samples : 0;
    int nrefs = 0;
    for (int k = 0; k < N; k++) {
        if (hits[k].face == RS_NO_HIT) {
            if (!env) continue;
            size_t pix = rs_skyenv_pixel(env, rays[k].dir);
            if (env->sun[pix] && Ns) continue;    /* the sun rays have it (none: count it here) */
            double pdf_c = rs_v3_dot(rays[k].dir, n) / M_PI, pdf_e = Ne ? rs_skyenv_pdf(env, pix) : 0;
            double wgt = Nc * pdf_c / (Nc * pdf_c + Ne * pdf_e) * M_PI / Nc;  /* L cos / pdf_c = pi L */
            add_sky(env, pix, wgt, out);
            double y = Nc * wgt * rs_skyenv_luminance(env->radiance + 3 * pix);
            out->cos_sum += y;
            out->cos_sum_sq += y * y;
            continue;
        }
        double L[3];
        rs_v3 x = rs_v3_add(rays[k].org, rs_v3_scale(rays[k].dir, hits[k].t));
        /* A back face is lit from the side nobody measured: it takes the facet's mean radiance. */
        int seen = !hits[k].backface && read_seen(g, hits[k].face, x, L);
        if (seen) {
            for (int ch = 0; ch < 3; ch++) out->gseen[ch] += L[ch];
            double y = M_PI * (0.2126 * L[0] + 0.7152 * L[1] + 0.0722 * L[2]);
            out->cos_sum += y;
            out->cos_sum_sq += y * y;
        }
        refs[nrefs].face = hits[k].face;
        refs[nrefs].unseen = (uint8_t)!seen;
        nrefs++;
    }
    double w = M_PI / N;                      /* cosine-weighted: E = pi * mean radiance */
    for (int ch = 0; ch < 3; ch++) out->gseen[ch] *= w;

    /* Rays drawn from the map: first the rest of the sky, then the sun set. With
     * sun_target_error > 0 the sun rays double (continuing the same Sobol sequence, so every
     * count is a power-of-two multiple of Ns and keeps its stratification) up to 16 x Ns until
     * the standard error of their estimate falls below that share of the facet's E_sky: only
     * facets that a shadow edge crosses need many. */
    out->rays = (uint32_t)N;
    for (int pass = 0; pass < 2; pass++) {
        int M = pass ? Ns : Ne, done = 0, goal = M, adaptive = pass && Ns && g->sun_target_error > 0;
        rs_facet_gather acc;
        memset(&acc, 0, sizeof acc);
        rs_facet_gather *dst = adaptive ? &acc : out;
        double div = adaptive ? 1 : Ns, sum = 0, sum_sq = 0;
        double y_sum = 0, y_sq = 0;                  /* each ray's value, for the noise estimate */
        while (done < goal) {
            int B = goal - done < M ? goal - done : M;     /* the scratch holds M rays */
            double *sp = s->samp;
            for (int i = 0; i < B; i++) {
                uint32_t k = (uint32_t)(done + i);
                double unused;
                rs_sobol2_owen(k, rs_hash_combine(seed, 3 + 3 * pass), &sp[5 * i], &sp[5 * i + 1]);  /* pixel, jitter u */
                rs_sobol2_owen(k, rs_hash_combine(seed, 4 + 3 * pass), &sp[5 * i + 2], &unused);     /* jitter v */
                rs_sobol2_owen(k, rs_hash_combine(seed, 5 + 3 * pass), &sp[5 * i + 3], &sp[5 * i + 4]); /* point */
            }
            guide_pick_batch(s, env, pass, sp, 5, B);
            for (int i = 0; i < B; i++) {
                size_t pix = s->pixels[i];
                int col = (int)(pix % (size_t)env->width), row = (int)(pix / (size_t)env->width);
                rs_v3 d = rs_pose_dir_to_world(&env->pose, rs_pano_uv_to_dir((col + sp[5 * i + 1]) / env->width,
                                                                             (row + sp[5 * i + 2]) / env->height));
                rs_v3 p = rs_triangle_point(a, b, c, sp[5 * i + 3], sp[5 * i + 4]);
                rays[i].org = rs_v3_add(p, rs_v3_scale(n, rs_scene_offset(g->scene, p)));
                rays[i].dir = d;
                rays[i].tnear = 0;
                rays[i].tfar = rs_v3_dot(d, n) > 0 ? INFINITY : 0;   /* below the horizon: no ray */
            }
            if (B && out->sees_nothing) memset(occl, 0, (size_t)B);
            else if (B) rs_scene_occluded(g->scene, rays, occl, (size_t)B);
            for (int i = 0; i < B; i++) {
                double cosn = rs_v3_dot(rays[i].dir, n);
                if (cosn <= 0 || occl[i]) continue;
                size_t pix = s->pixels[i];
                double lum = rs_skyenv_luminance(env->radiance + 3 * pix), wgt;
                if (pass)                                    /* L cos / pdf / Ns, pdf = lum / power */
                    wgt = cosn * env->sun_power / (lum * div);
                else                                         /* balance heuristic, already / Ne */
                    wgt = cosn / (Nc * cosn / M_PI + Ne * rs_skyenv_pdf(env, pix));
                add_sky(env, pix, wgt, dst);
                double y = (pass ? div : Ne) * wgt * lum;   /* this ray alone: its estimate of the whole */
                y_sum += y;
                y_sq += y * y;
                sum += cosn * env->sun_power;                /* the ray's luminance contribution */
                sum_sq += (cosn * env->sun_power) * (cosn * env->sun_power);
            }
            done += B;
            if (adaptive && done == goal && goal < 16 * Ns) {
                double mean = sum / done, se = sqrt(fmax(0, sum_sq / done - mean * mean) / done);
                if (se > g->sun_target_error * (out->esky_lum + mean)) goal *= 2;
            }
        }
        if (done) {                                  /* rays that brought nothing count as 0 */
            double mean = y_sum / done;
            out->map_var += fmax(0, y_sq / done - mean * mean) / done;
        }
        if (adaptive) {
            for (int ch = 0; ch < 3; ch++) out->esky[ch] += acc.esky[ch] / done;
            out->esky_lum += acc.esky_lum / done;
            out->filled_lum += acc.filled_lum / done;
        }
        out->rays += (uint32_t)done;
    }

    /* K row: merge hits per facet j (sorted, so the file does not depend on thread timing).
     * An entry is its hit count times w, rounded to float once: adding w up in float drifted
     * by about 1e-6 and let row sums pass pi (found by tests/stress/test_cavity.c). */
    qsort(refs, (size_t)nrefs, sizeof *refs, cmp_hit);
    if (nrefs) {
        out->entries = malloc((size_t)nrefs * sizeof *out->entries);
        if (!out->entries) return -1;
    }
    for (int k = 0; k < nrefs;) {
        int first = k, unseen = 0;
        for (; k < nrefs && refs[k].face == refs[first].face; k++) unseen += refs[k].unseen != 0;
        rs_kentry *e = &out->entries[out->nentries++];
        e->col = refs[first].face;
        e->k = (float)((k - first) * w);
        e->k_unseen = (float)(unseen * w);
    }
    return 0;
}


double rs_gather_mc_sigma(const rs_facet_gather *fg, int samples, const double *radiance, const uint8_t *observed)
{
    if (!fg->rays || samples < 1) return 0;
    /* A hit count k_unseen N / pi for each K entry: its rays' values are pi L_j each. */
    double n = samples, s1 = fg->cos_sum, s2 = fg->cos_sum_sq;
    for (uint32_t q = 0; radiance && q < fg->nentries; q++) {
        const rs_kentry *en = &fg->entries[q];
        if (observed && !observed[en->col]) continue;
        const double *L = radiance + 3 * (size_t)en->col;
        double y = M_PI * (0.2126 * L[0] + 0.7152 * L[1] + 0.0722 * L[2]), hits = en->k_unseen * n / M_PI;
        s1 += hits * y;
        s2 += hits * y * y;
    }
    double mean = s1 / n, var_cos = fmax(0, s2 / n - mean * mean) / n;
    return sqrt(var_cos + fg->map_var);
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
                             const uint8_t *observed, size_t max_facets, double *factor, size_t *used)
{
    *factor = 1;
    if (used) *used = 0;
    size_t n = 0;
    for (size_t f = 0; f < nf; f++) n += fg[f].rays > 0;
    if (!n || !max_facets) return 0;
    size_t stride = (n + max_facets - 1) / max_facets, m = 0;
    uint32_t *list = malloc(((n + stride - 1) / stride + 1) * sizeof *list);
    double *z2 = calloc((n + stride - 1) / stride + 1, sizeof *z2);
    if (!list || !z2) {
        free(list);
        free(z2);
        return -1;
    }
    for (size_t f = 0, k = 0; f < nf; f++)
        if (fg[f].rays > 0 && k++ % stride == 0) list[m++] = (uint32_t)f;
    rs_gather_ctx g2 = *g;
    g2.seed = g->seed ^ 0x5bd1e995u;                /* an independent scrambling */
    size_t scratch = (size_t)g->samples;
    if ((size_t)g->sky_samples > scratch) scratch = (size_t)g->sky_samples;
    if ((size_t)g->sun_samples > scratch) scratch = (size_t)g->sun_samples;
    int failed = 0;
#pragma omp parallel
    {
        rs_gather_scratch *s = rs_gather_scratch_new(scratch);
        int mine_failed = !s;
#pragma omp for schedule(dynamic, 4)
        for (size_t k = 0; k < m; k++) {
            rs_facet_gather r;
            z2[k] = -1;
            if (mine_failed || rs_gather_facet(&g2, list[k], s, &r) != 0) {
                mine_failed = 1;
                continue;
            }
            const rs_facet_gather *a = &fg[list[k]];
            double sa = rs_gather_mc_sigma(a, g->samples, radiance, observed);
            double sb = rs_gather_mc_sigma(&r, g->samples, radiance, observed);
            double d = facet_lum(a, radiance, observed) - facet_lum(&r, radiance, observed);
            if (sa + sb > 0) z2[k] = d * d / (sa * sa + sb * sb);   /* var(E - E') = sa^2 + sb^2 */
            free(r.entries);
        }
        if (mine_failed) {
#pragma omp atomic write
            failed = 1;
        }
        rs_gather_scratch_free(s);
    }
    double sum = 0;
    size_t cnt = 0;
    for (size_t k = 0; k < m; k++)
        if (z2[k] >= 0) sum += z2[k], cnt++;
    free(list);
    free(z2);
    if (failed) return -1;
    if (cnt) *factor = sqrt(sum / cnt);
    if (used) *used = cnt;
    return 0;
}

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

/* Gathers the listed facets in parallel; -1 when a thread ran out of memory. */
static int gather_list(const rs_gather_ctx *g, const uint32_t *list, size_t n, rs_facet_gather *fg,
                       struct rs_progress *prog)
{
    size_t scratch = (size_t)g->samples;
    if ((size_t)g->sky_samples > scratch) scratch = (size_t)g->sky_samples;
    if ((size_t)g->sun_samples > scratch) scratch = (size_t)g->sun_samples;
    int failed = 0;
#pragma omp parallel
    {
        rs_gather_scratch *s = rs_gather_scratch_new(scratch);
        int mine_failed = !s;
        /* Dynamic chunks of neighbouring facets: costs differ a lot (a roof's rays escape at
         * once, a courtyard's bounce), and neighbours share BVH nodes in the cache. */
#pragma omp for schedule(dynamic, 16)
        for (size_t k = 0; k < n; k++) {
            if (mine_failed || failed) continue;
            if (rs_gather_facet(g, list[k], s, &fg[list[k]]) != 0) mine_failed = 1;
            if (prog && (k & 255) == 255) rs_progress_add(prog, 256);
        }
        if (mine_failed) {
#pragma omp atomic write
            failed = 1;
        }
        rs_gather_scratch_free(s);
    }
    return failed ? -1 : 0;
}

int rs_gather_run(const rs_gather_ctx *g, size_t nf, const uint8_t *needed, rs_facet_gather *fg, uint8_t *gathered,
                  struct rs_progress *prog, rs_gather_stats *stats)
{
    memset(stats, 0, sizeof *stats);
    memset(fg, 0, nf * sizeof *fg);
    uint32_t *order = morton_order(rs_scene_mesh(g->scene), nf), *list = malloc((nf ? nf : 1) * sizeof *list);
    uint8_t *state = calloc(nf ? nf : 1, 1);        /* 0 not reached, 1 queued, 2 gathered */
    int rc = -1;
    if (!order || !list || !state) goto out;
    for (size_t f = 0; f < nf; f++) state[f] = !needed || needed[f];
    for (;;) {
        size_t n = 0;
        for (size_t k = 0; k < nf; k++)
            if (state[order[k]] == 1) list[n++] = order[k];
        if (!n) break;
        if (gather_list(g, list, n, fg, prog) != 0) goto out;
        stats->waves++;
        stats->gathered += n;
        for (size_t k = 0; k < n; k++) state[list[k]] = 2;
        for (size_t k = 0; k < n; k++)                 /* what these facets' rays reached comes next */
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
    return rc;
}

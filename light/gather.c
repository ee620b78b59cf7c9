/* gather: hemisphere gather per facet (see gather.h and irradiance.c). Cosine-weighted
 * Owen-scrambled Sobol directions from Sobol points spread over the facet; explicit shadow rays
 * toward the sky map's bright pixels, chosen by power. */
#include "light/gather.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include "common/log.h"
#include "common/sampling.h"
#include "sky/skysh.h"

typedef struct {
    uint32_t face;
    uint8_t unseen; /* the radiance at the hit point was not read from the panorama */
} hit_ref;

/* The search guide a scratch uses for one distribution (skyenv.h: rs_skyenv_guide_build): the
 * map's own when it has one, else one built here on first use (maps made by hand in tests). */
enum { GUIDE_BUCKETS = RS_SKYENV_GUIDE_BUCKETS };
typedef struct {
    const double *cdf; /* the distribution it serves (NULL: none yet) */
    const uint32_t *guide;
    uint32_t own[GUIDE_BUCKETS + 1];
} sky_guide;

struct rs_gather_scratch {
    sky_guide sky, sun;      /* chosen on first use: a scratch serves one sky map for its life */
    const rs_mesh *box_mesh; /* the mesh whose bounding box lo/hi holds (NULL: not computed) */
    float lo[3], hi[3];
    rs_ray *rays;
    rs_hit *hits;
    hit_ref *refs;
    size_t nrefs_cap;              /* entries refs holds: an adaptive facet's hits grow it */
    uint32_t *pixels;              /* sky pixel of each map-sampled ray */
    size_t *ray_pixel;             /* per cosine ray: the sky map's or the panorama's pixel it reads */
    double *samp;                  /* 5 per ray: the Sobol coordinates of a map-sampled ray */
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
    s->nrefs_cap = n;
    s->pixels = malloc(n * sizeof *s->pixels);
    s->ray_pixel = malloc(n * sizeof *s->ray_pixel);
    s->samp = malloc(5 * n * sizeof *s->samp);
    s->range_lo = malloc(n * sizeof *s->range_lo);
    s->range_hi = malloc(n * sizeof *s->range_hi);
    s->occl = malloc(n);
    if (!s->rays || !s->hits || !s->refs || !s->pixels || !s->ray_pixel || !s->samp || !s->range_lo || !s->range_hi ||
        !s->occl) {
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
    free(s->ray_pixel);
    free(s->samp);
    free(s->range_lo);
    free(s->range_hi);
    free(s->occl);
    free(s);
}

static const uint32_t *guide_for(sky_guide *g, const double *cdf, const uint32_t *shared, size_t npx)
{
    if (g->cdf != cdf) {
        if (shared) {
            g->guide = shared;
        } else {
            rs_skyenv_guide_build(cdf, npx, g->own);
            g->guide = g->own;
        }
        g->cdf = cdf;
    }
    return g->guide;
}

/* The pixel rs_skyenv_pick (or _pick_sun) returns for x, found through the guide: the first k
 * with cdf[k + 1] > x * total lies in [guide[b], guide[b + 1]] for b = floor(x * buckets). */
static size_t guide_pick(sky_guide *g, const double *cdf, const uint32_t *shared, size_t npx, double x)
{
    const uint32_t *guide = guide_for(g, cdf, shared, npx);
    double target = x * cdf[npx];
    size_t b = (size_t)(x * GUIDE_BUCKETS);
    if (b >= GUIDE_BUCKETS) b = GUIDE_BUCKETS - 1;
    size_t lo = guide[b], hi = guide[b + 1];
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (cdf[mid + 1] > target)
            hi = mid;
        else
            lo = mid + 1;
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
    return sun ? guide_pick(&s->sun, env->sun_cdf, env->sun_cdf_guide, npx, x)
               : guide_pick(&s->sky, env->cdf, env->cdf_guide, npx, x);
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
        rs_v3 corner =
            rs_v3_make(k & 1 ? s->hi[0] : s->lo[0], k & 2 ? s->hi[1] : s->lo[1], k & 4 ? s->hi[2] : s->lo[2]);
        top = fmax(top, rs_v3_dot(n, rs_v3_sub(corner, a)));
    }
    return top <= eps;
}

/* guide_pick for B values at once, in three sweeps so that the cache misses of different picks
 * overlap instead of queueing (the map's CDF is megabytes, each pick a random place in it):
 * the guide entries, then the first CDF probe of each range, then the searches. */
static void guide_pick_batch(rs_gather_scratch *s, const rs_skyenv *env, int sun, const double *x, int stride, int B)
{
    const double *cdf = sun ? env->sun_cdf : env->cdf;
    size_t npx = (size_t)env->width * env->height;
    const uint32_t *guide = guide_for(sun ? &s->sun : &s->sky, cdf, sun ? env->sun_cdf_guide : env->cdf_guide, npx);
    for (int i = 0; i < B; i++) {
        size_t b = (size_t)(x[i * stride] * GUIDE_BUCKETS);
        __builtin_prefetch(&guide[b < GUIDE_BUCKETS ? b : GUIDE_BUCKETS - 1]);
    }
    for (int i = 0; i < B; i++) {
        size_t b = (size_t)(x[i * stride] * GUIDE_BUCKETS);
        if (b >= GUIDE_BUCKETS) b = GUIDE_BUCKETS - 1;
        s->range_lo[i] = guide[b];
        s->range_hi[i] = guide[b + 1];
        __builtin_prefetch(&cdf[s->range_lo[i] + (s->range_hi[i] - s->range_lo[i]) / 2 + 1]);
    }
    for (int i = 0; i < B; i++) {
        double target = x[i * stride] * cdf[npx];
        size_t lo = s->range_lo[i], hi = s->range_hi[i];
        while (lo < hi) {
            size_t mid = lo + (hi - lo) / 2;
            if (cdf[mid + 1] > target)
                hi = mid;
            else
                lo = mid + 1;
        }
        if (lo >= npx) { /* as in guide_pick */
            lo = npx - 1;
            while (lo > 0 && cdf[lo + 1] == cdf[lo]) lo--;
        }
        s->pixels[i] = (uint32_t)lo;
        __builtin_prefetch(env->radiance + 3 * lo); /* read after the shadow rays */
        __builtin_prefetch(&env->filled[lo]);
    }
}

static int cmp_hit(const void *a, const void *b)
{
    const hit_ref *x = a, *y = b;
    if (x->face != y->face) return x->face < y->face ? -1 : 1;
    return (int)x->unseen - (int)y->unseen;
}

/* The panorama pixel that sees world point x (SIZE_MAX: no capture to read). */
static size_t seen_pixel(const rs_gather_ctx *g, rs_v3 x)
{
    const rs_capture *cap = g->cap;
    if (!cap) return SIZE_MAX;
    int c, r;
    rs_pano_world_to_pixel(&cap->pose, cap->pano->width, cap->pano->height, rs_v3_sub(x, cap->pose.position), &c, &r);
    return (size_t)r * cap->pano->width + c;
}

/* The panorama's radiance at pixel k (seen_pixel) when that pixel sees facet j there. */
static int read_seen(const rs_gather_ctx *g, uint32_t j, size_t k, double out[3])
{
    if (k == SIZE_MAX || g->facet_id[k] != (float)j) return 0;
    const float *px = g->cap->pano->data + 3 * k;
    if (!rs_capture_pixel_ok(px)) return 0;
    for (int ch = 0; ch < 3; ch++) out[ch] = px[ch];
    return 1;
}

/* Adds weight * (sky radiance of pixel pix) to E_sky, and to its sun part when pix is in the
 * sun set, whichever kind of ray brought it (cosine rays do when there are no sun rays); dir is
 * the ray's world direction (for the filled light's direction moments). */
static void add_sky(const rs_skyenv *env, size_t pix, rs_v3 dir, double weight, rs_facet_gather *out)
{
    const float *L = env->radiance + 3 * pix;
    for (int ch = 0; ch < 3; ch++) out->esky[ch] += weight * L[ch];
    if (env->sun[pix])
        for (int ch = 0; ch < 3; ch++) out->esun[ch] += weight * L[ch];
    double lum = weight * rs_skyenv_luminance(L);
    out->esky_lum += lum;
    if (env->filled[pix]) {
        out->filled_lum += lum;
        if (env->fill_sigma_px) {
            out->fill_sigma_lum += lum * env->fill_sigma_px[pix];
            for (int ch = 0; ch < 3; ch++) {
                double u = weight * L[ch] * env->fill_sigma_px[pix];
                out->fill_sigma_rgb[ch] += u;
                out->fill_sigma_dir[0][ch] += u * dir.x;
                out->fill_sigma_dir[1][ch] += u * dir.y;
            }
        }
    }
}

/* What one facet's rounds of rays share (rs_gather_ctx target_error): its geometry, the refs
 * of its rays that hit facets, and the per-ray values of its map-drawn rays, per pass. */
typedef struct {
    rs_v3 n, a, b, c;
    uint32_t seed;
    int nrefs;
    double inv_dist_sum;      /* cosine rays: sum of 1 / hit distance */
    double y_sum[2], y_sq[2]; /* map rays (pass 0 sky, 1 sun): each ray's estimate of the whole */
    int done[2];              /* map rays so far, per pass */
} facet_state;

/* Room for `more` further refs in the scratch (an adaptive facet's hits outgrow samples). */
static int refs_reserve(rs_gather_scratch *s, size_t more)
{
    if (s->nrefs_cap >= more) return 0;
    size_t cap = s->nrefs_cap ? s->nrefs_cap : 64;
    while (cap < more) cap *= 2;
    hit_ref *r = realloc(s->refs, cap * sizeof *r);
    if (!r) return -1;
    s->refs = r;
    s->nrefs_cap = cap;
    return 0;
}

/* One round of a facet's rays: cosine rays [c0, c0 + nc) of its Sobol sequences, then rays
 * [m0 * M, (m0 + mul) * M) of each map pass (M = sky_samples, sun_samples), every one weighted
 * for the base counts (samples, sky_samples, sun_samples): a round that doubles every count
 * leaves the MIS weights as they are, and rs_gather_facet divides the sums by the factor at the
 * end. Round 0 (c0 = m0 = 0, mul = 1) is the whole gather when target_error is 0. */
static int gather_round(const rs_gather_ctx *g, rs_gather_scratch *s, facet_state *st, int c0, int nc, int m0, int mul,
                        rs_facet_gather *out)
{
    rs_ray *rays = s->rays;
    rs_hit *hits = s->hits;
    uint8_t *occl = s->occl;
    rs_v3 n = st->n, a = st->a, b = st->b, c = st->c;
    uint32_t seed = st->seed;
    int N = g->samples;
    const rs_skyenv *env = g->env;
    /* The sky is split in two. The sun set (small, very bright) gets Ns rays of its own, chosen
     * by power. The rest is sampled two ways combined by multiple importance sampling (Veach
     * 1997, balance heuristic): the cosine-weighted rays above and Ne rays drawn from the map's
     * distribution. Cosine rays that land in the sun set count nothing: the sun rays have it. */
    int Nc = N, Ne = env && env->cdf ? g->sky_samples : 0, Ns = env && env->sun_cdf ? g->sun_samples : 0;
    for (int k0 = c0; k0 < c0 + nc; k0 += N) { /* the scratch holds N rays */
        int B = c0 + nc - k0 < N ? c0 + nc - k0 : N;
        for (int i = 0; i < B; i++) {
            uint32_t k = (uint32_t)(k0 + i);
            double x, y, px, py;
            rs_sobol2_owen(k, rs_hash_combine(seed, 1), &x, &y);
            rs_sobol2_owen(k, rs_hash_combine(seed, 2), &px, &py);
            rs_v3 p = rs_triangle_point(a, b, c, px, py);
            rays[i].org = rs_v3_add(p, rs_v3_scale(n, rs_scene_offset(g->scene, p)));
            rays[i].dir = rs_cosine_hemisphere(n, x, y);
            rays[i].tnear = 0;
            rays[i].tfar = INFINITY;
        }
        if (out->sees_nothing) /* the answer Embree would give, without asking */
            for (int i = 0; i < B; i++) hits[i].face = RS_NO_HIT;
        else
            rs_scene_intersect(g->scene, rays, hits, (size_t)B);
        if (refs_reserve(s, (size_t)st->nrefs + (size_t)B) != 0) return -1;
        hit_ref *refs = s->refs;
        /* First the pixel each ray reads (the sky map's where it escaped, the panorama's where
         * it hit a front face), prefetched: the maps are tens of megabytes, and one ray's cache
         * misses after another's were a quarter of this loop's time (perf). */
        size_t *pixel = s->ray_pixel;
        for (int i = 0; i < B; i++) {
            if (hits[i].face == RS_NO_HIT) {
                if (!env) continue;
                size_t pix = rs_skyenv_pixel(env, rays[i].dir);
                __builtin_prefetch(&env->sun[pix]);
                __builtin_prefetch(env->radiance + 3 * pix);
                __builtin_prefetch(&env->filled[pix]);
                if (env->fill_sigma_px) __builtin_prefetch(&env->fill_sigma_px[pix]);
                pixel[i] = pix;
            } else if (!hits[i].backface) {
                rs_v3 x = rs_v3_add(rays[i].org, rs_v3_scale(rays[i].dir, hits[i].t));
                size_t k = seen_pixel(g, x);
                if (k != SIZE_MAX) {
                    __builtin_prefetch(&g->facet_id[k]);
                    __builtin_prefetch(g->cap->pano->data + 3 * k);
                }
                pixel[i] = k;
            }
        }
        for (int i = 0; i < B; i++) {
            if (hits[i].face == RS_NO_HIT) {
                if (!env) continue;
                size_t pix = pixel[i];
                if (env->sun[pix] && Ns) continue; /* the sun rays have it (none: count it here) */
                double pdf_c = rs_v3_dot(rays[i].dir, n) / M_PI, pdf_e = Ne ? rs_skyenv_pdf(env, pix) : 0;
                double wgt = Nc * pdf_c / (Nc * pdf_c + Ne * pdf_e) * M_PI / Nc; /* L cos / pdf_c = pi L */
                add_sky(env, pix, rays[i].dir, wgt, out);
                double y = Nc * wgt * rs_skyenv_luminance(env->radiance + 3 * pix);
                out->cos_sum += y;
                out->cos_sum_sq += y * y;
                continue;
            }
            st->inv_dist_sum += 1.0 / fmax(hits[i].t, 1e-6);
            double L[3];
            /* A back face is lit from the side nobody measured: it takes the facet's mean radiance. */
            int seen = !hits[i].backface && read_seen(g, hits[i].face, pixel[i], L);
            if (seen) {
                for (int ch = 0; ch < 3; ch++) out->gseen[ch] += L[ch];
                double y = M_PI * (0.2126 * L[0] + 0.7152 * L[1] + 0.0722 * L[2]);
                out->cos_sum += y;
                out->cos_sum_sq += y * y;
            }
            refs[st->nrefs].face = hits[i].face;
            refs[st->nrefs].unseen = (uint8_t)!seen;
            st->nrefs++;
        }
    }

    /* Rays drawn from the map: first the rest of the sky, then the sun set. With
     * sun_target_error > 0 (and no target_error) the sun rays double (continuing the same Sobol
     * sequence, so every count is a power-of-two multiple of Ns and keeps its stratification) up
     * to 16 x Ns until the standard error of their estimate falls below that share of the
     * facet's E_sky: only facets that a shadow edge crosses need many. */
    for (int pass = 0; pass < 2; pass++) {
        int M = pass ? Ns : Ne, first = m0 * M, done = first, goal = first + mul * M;
        int adaptive = pass && Ns && g->sun_target_error > 0 && !(g->target_error > 0);
        rs_facet_gather acc;
        memset(&acc, 0, sizeof acc);
        rs_facet_gather *dst = adaptive ? &acc : out;
        double div = adaptive ? 1 : Ns, sum = 0, sum_sq = 0;
        while (done < goal) {
            int B = goal - done < M ? goal - done : M; /* the scratch holds M rays */
            double *sp = s->samp;
            for (int i = 0; i < B; i++) {
                uint32_t k = (uint32_t)(done + i);
                double unused;
                rs_sobol2_owen(k, rs_hash_combine(seed, 3 + 3 * pass), &sp[5 * i],
                               &sp[5 * i + 1]);                                                  /* pixel, jitter u */
                rs_sobol2_owen(k, rs_hash_combine(seed, 4 + 3 * pass), &sp[5 * i + 2], &unused); /* jitter v */
                rs_sobol2_owen(k, rs_hash_combine(seed, 5 + 3 * pass), &sp[5 * i + 3], &sp[5 * i + 4]); /* point */
            }
            guide_pick_batch(s, env, pass, sp, 5, B);
            for (int i = 0; i < B; i++) {
                size_t pix = s->pixels[i];
                int col = (int)(pix % (size_t)env->width), row = (int)(pix / (size_t)env->width);
                rs_v3 d = rs_pose_dir_to_world(
                    &env->pose,
                    rs_pano_uv_to_dir((col + sp[5 * i + 1]) / env->width, (row + sp[5 * i + 2]) / env->height));
                rs_v3 p = rs_triangle_point(a, b, c, sp[5 * i + 3], sp[5 * i + 4]);
                rays[i].org = rs_v3_add(p, rs_v3_scale(n, rs_scene_offset(g->scene, p)));
                rays[i].dir = d;
                rays[i].tnear = 0;
                rays[i].tfar = rs_v3_dot(d, n) > 0 ? INFINITY : 0; /* below the horizon: no ray */
            }
            if (B > 0 && out->sees_nothing)
                memset(occl, 0, (size_t)B);
            else if (B)
                rs_scene_occluded(g->scene, rays, occl, (size_t)B);
            for (int i = 0; i < B; i++) {
                double cosn = rs_v3_dot(rays[i].dir, n);
                if (cosn <= 0 || occl[i]) continue;
                size_t pix = s->pixels[i];
                double lum = rs_skyenv_luminance(env->radiance + 3 * pix), wgt;
                if (pass) /* L cos / pdf / Ns, pdf = lum / power */
                    wgt = cosn * env->sun_power / (lum * div);
                else /* balance heuristic, already / Ne */
                    wgt = cosn / (Nc * cosn / M_PI + Ne * rs_skyenv_pdf(env, pix));
                add_sky(env, pix, rays[i].dir, wgt, dst);
                double y = (pass ? div : Ne) * wgt * lum; /* this ray alone: its estimate of the whole */
                st->y_sum[pass] += y;
                st->y_sq[pass] += y * y;
                sum += cosn * env->sun_power; /* the ray's luminance contribution */
                sum_sq += (cosn * env->sun_power) * (cosn * env->sun_power);
            }
            done += B;
            if (adaptive && done == goal && goal < 16 * Ns) {
                double mean = sum / done, se = sqrt(fmax(0, sum_sq / done - mean * mean) / done);
                if (se > g->sun_target_error * (out->esky_lum + mean)) goal *= 2;
            }
        }
        if (adaptive) {
            for (int ch = 0; ch < 3; ch++) {
                out->esky[ch] += acc.esky[ch] / done;
                out->esun[ch] += acc.esun[ch] / done;
            }
            out->esky_lum += acc.esky_lum / done;
            out->filled_lum += acc.filled_lum / done;
            out->fill_sigma_lum += acc.fill_sigma_lum / done;
            for (int ch = 0; ch < 3; ch++) {
                out->fill_sigma_rgb[ch] += acc.fill_sigma_rgb[ch] / done;
                for (int k = 0; k < 2; k++) out->fill_sigma_dir[k][ch] += acc.fill_sigma_dir[k][ch] / done;
            }
        }
        st->done[pass] += done - first;
    }
    return 0;
}

/* Standard error of the luminance of E_sky + G after rounds giving `factor` times the base
 * counts, and that luminance (*e), by rs_gather_mc_sigma's formula; rays that hit facet j
 * through K carry pi L_j when the context has the radiance and j is observed. */
static double round_sigma(const rs_gather_ctx *g, const rs_gather_scratch *s, const facet_state *st,
                          const rs_facet_gather *out, int factor, double *e)
{
    double nc = (double)g->samples * factor, s1 = out->cos_sum, s2 = out->cos_sum_sq, kl = 0;
    for (int q = 0; g->radiance && q < st->nrefs; q++) {
        uint32_t j = s->refs[q].face;
        if (!s->refs[q].unseen || (g->observed && !g->observed[j])) continue;
        const double *L = g->radiance + 3 * (size_t)j;
        double y = M_PI * (0.2126 * L[0] + 0.7152 * L[1] + 0.0722 * L[2]);
        s1 += y;
        s2 += y * y;
        kl += y;
    }
    double gl = M_PI * (0.2126 * out->gseen[0] + 0.7152 * out->gseen[1] + 0.0722 * out->gseen[2]);
    *e = out->esky_lum / factor + (gl + kl) / nc;
    double mean = s1 / nc, var = fmax(0, s2 / nc - mean * mean) / nc;
    for (int pass = 0; pass < 2; pass++)
        if (st->done[pass]) {
            double m = st->y_sum[pass] / st->done[pass];
            var += fmax(0, st->y_sq[pass] / st->done[pass] - m * m) / st->done[pass];
        }
    return sqrt(var);
}

/* Gathers one facet; rays/hits/refs are the thread's scratch (samples entries each; refs grow).
 * With target_error > 0 it gathers in rounds: the base counts, then each round as many rays
 * again of every kind (continuing the sequences, so each count stays a power-of-two multiple of
 * the base and keeps its stratification), up to RS_GATHER_MAX_ROUNDS doublings, until the
 * standard error of E_sky + G falls below target_error times it. */
int rs_skysh_facet(const rs_skysh *sh, rs_v3 n, rs_facet_gather *out)
{
    double e[RS_SKYSH_CHANNELS], es[RS_SKYSH_CHANNELS], bound;
    if (!rs_skysh_sky_only(sh, n, e, es, &bound)) return 0;
    memset(out, 0, sizeof *out);
    for (int ch = 0; ch < 3; ch++) {
        out->esky[ch] = e[ch] + es[ch];
        out->esun[ch] = es[ch];
    }
    out->esky_lum = rs_skyenv_luminance3(out->esky);
    out->filled_lum = e[3] + es[3];
    out->fill_sigma_lum = fmax(0, e[4]) + es[4];
    /* the harmonics carry the uncertain light's luminance only: its colour taken as E_sky's */
    for (int ch = 0; ch < 3; ch++) {
        double colour = out->esky_lum > 0 ? out->esky[ch] / out->esky_lum : 0;
        out->fill_sigma_rgb[ch] = out->fill_sigma_lum * colour;
        out->fill_sigma_dir[0][ch] = (e[5] + es[5]) * colour;
        out->fill_sigma_dir[1][ch] = (e[6] + es[6]) * colour;
    }
    out->sees_nothing = 1;
    out->sky_sh = 1;
    out->sh_sigma = bound * rs_skyenv_luminance3(e);
    return 1;
}

int rs_gather_facet(const rs_gather_ctx *g, uint32_t f, rs_gather_scratch *s, rs_facet_gather *out)
{
    memset(out, 0, sizeof *out);
    const rs_mesh *m = rs_scene_mesh(g->scene);
    rs_v3 n = rs_scene_normal(g->scene, f);
    if (rs_v3_len(n) == 0) return 0; /* degenerate: no irradiance, not estimable */
    rs_v3 a = rs_mesh_vert(m, m->tris[3 * f]), b = rs_mesh_vert(m, m->tris[3 * f + 1]),
          c = rs_mesh_vert(m, m->tris[3 * f + 2]);
    /* Only sky above the plane and a smooth sky: its harmonic projection, no ray (skysh.h). */
    if (g->sky_sh && g->skip_convex && sees_nothing(g, s, n, a) && rs_skysh_facet(g->sky_sh, n, out)) return 0;
    facet_state st;
    memset(&st, 0, sizeof st);
    st.n = n, st.a = a, st.b = b, st.c = c;
    st.seed = rs_hash_combine(g->seed, f);
    int N = g->samples, rounds = 0;
    out->sees_nothing = (uint8_t)(g->skip_convex && sees_nothing(g, s, n, a));
    if (gather_round(g, s, &st, 0, N, 0, 1, out) != 0) return -1;
    while (g->target_error > 0 && rounds < RS_GATHER_MAX_ROUNDS) {
        double e, se = round_sigma(g, s, &st, out, 1 << rounds, &e);
        if (!(se > g->target_error * e)) break;
        if (gather_round(g, s, &st, N << rounds, N << rounds, 1 << rounds, 1 << rounds, out) != 0) return -1;
        rounds++;
    }
    if (rounds) { /* every sum was weighted for the base counts */
        double inv = 1.0 / (1 << rounds);
        for (int ch = 0; ch < 3; ch++) {
            out->esky[ch] *= inv;
            out->esun[ch] *= inv;
        }
        out->esky_lum *= inv;
        out->filled_lum *= inv;
        out->fill_sigma_lum *= inv;
        for (int ch = 0; ch < 3; ch++) {
            out->fill_sigma_rgb[ch] *= inv;
            for (int k = 0; k < 2; k++) out->fill_sigma_dir[k][ch] *= inv;
        }
    }
    double w = M_PI / ((double)N * (1 << rounds)); /* cosine-weighted: E = pi * mean radiance */
    for (int ch = 0; ch < 3; ch++) out->gseen[ch] *= w;
    out->inv_dist = st.inv_dist_sum / ((double)N * (1 << rounds));
    for (int pass = 0; pass < 2; pass++) /* rays that brought nothing count as 0 */
        if (st.done[pass]) {
            double mean = st.y_sum[pass] / st.done[pass];
            out->map_var += fmax(0, st.y_sq[pass] / st.done[pass] - mean * mean) / st.done[pass];
        }
    out->rounds = (uint8_t)rounds;
    out->samples = (uint32_t)N;
    out->rays = (uint32_t)(N << rounds) + (uint32_t)st.done[0] + (uint32_t)st.done[1];

    /* K row: merge hits per facet j (sorted, so the file does not depend on thread timing).
     * An entry is its hit count times w, rounded to float once: adding w up in float drifted
     * by about 1e-6 and let row sums pass pi (found by tests/stress/test_cavity.c). */
    hit_ref *refs = s->refs;
    int nrefs = st.nrefs;
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

double rs_gather_mc_sigma(const rs_facet_gather *fg, const double *radiance, const uint8_t *observed)
{
    if (!fg->rays || !fg->samples) return 0;
    /* A hit count k_unseen N / pi for each K entry: its rays' values are pi L_j each. */
    double n = (double)fg->samples * (1 << fg->rounds), s1 = fg->cos_sum, s2 = fg->cos_sum_sq;
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

void rs_gather_inter_observed(const rs_facet_gather *fg, const double *radiance, const uint8_t *observed, double g[3])
{
    for (int ch = 0; ch < 3; ch++) g[ch] = fg->gseen[ch];
    for (uint32_t q = 0; q < fg->nentries; q++) {
        const rs_kentry *en = &fg->entries[q];
        if (observed[en->col])
            for (int ch = 0; ch < 3; ch++) g[ch] += en->k_unseen * radiance[3 * en->col + ch];
    }
}

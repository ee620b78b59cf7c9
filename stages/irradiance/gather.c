/* gather: hemisphere gather per facet (see gather.h and irradiance.c). Cosine-weighted
 * Owen-scrambled Sobol directions from Sobol points spread over the facet; explicit shadow rays
 * toward the sky map's bright pixels, chosen by power. */
#include "gather.h"

#include <stdlib.h>
#include <string.h>
#include "sampling.h"

typedef struct {
    uint32_t face;
    uint8_t unseen;            /* the radiance at the hit point was not read from the panorama */
} hit_ref;

struct rs_gather_scratch {
    rs_ray *rays;
    rs_hit *hits;
    hit_ref *refs;
    uint32_t *pixels;          /* sky pixel of each map-sampled ray */
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
    s->occl = malloc(n);
    if (!s->rays || !s->hits || !s->refs || !s->pixels || !s->occl) {
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
    free(s->occl);
    free(s);
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
            if (env->sun[pix]) continue;
            double pdf_c = rs_v3_dot(rays[k].dir, n) / M_PI, pdf_e = Ne ? rs_skyenv_pdf(env, pix) : 0;
            double wgt = Nc * pdf_c / (Nc * pdf_c + Ne * pdf_e) * M_PI / Nc;  /* L cos / pdf_c = pi L */
            add_sky(env, pix, wgt, out);
            continue;
        }
        double L[3];
        rs_v3 x = rs_v3_add(rays[k].org, rs_v3_scale(rays[k].dir, hits[k].t));
        /* A back face is lit from the side nobody measured: it takes the facet's mean radiance. */
        int seen = !hits[k].backface && read_seen(g, hits[k].face, x, L);
        if (seen)
            for (int ch = 0; ch < 3; ch++) out->gseen[ch] += L[ch];
        refs[nrefs].face = hits[k].face;
        refs[nrefs].unseen = (uint8_t)!seen;
        nrefs++;
    }
    double w = M_PI / N;                      /* cosine-weighted: E = pi * mean radiance */
    for (int ch = 0; ch < 3; ch++) out->gseen[ch] *= w;

    /* Rays drawn from the map: first the rest of the sky, then the sun set. */
    for (int pass = 0; pass < 2; pass++) {
        int M = pass ? Ns : Ne;
        for (int k = 0; k < M; k++) {
            double x, y, z, unused, px, py;
            rs_sobol2_owen((uint32_t)k, rs_hash_combine(seed, 3 + 3 * pass), &x, &y);       /* pixel, jitter u */
            rs_sobol2_owen((uint32_t)k, rs_hash_combine(seed, 4 + 3 * pass), &z, &unused);  /* jitter v */
            rs_sobol2_owen((uint32_t)k, rs_hash_combine(seed, 5 + 3 * pass), &px, &py);     /* point */
            size_t pix = pass ? rs_skyenv_pick_sun(env, x) : rs_skyenv_pick(env, x);
            int col = (int)(pix % (size_t)env->width), row = (int)(pix / (size_t)env->width);
            rs_v3 d = rs_pose_dir_to_world(&env->pose, rs_pano_uv_to_dir((col + y) / env->width,
                                                                         (row + z) / env->height));
            rs_v3 p = rs_triangle_point(a, b, c, px, py);
            rays[k].org = rs_v3_add(p, rs_v3_scale(n, rs_scene_offset(g->scene, p)));
            rays[k].dir = d;
            rays[k].tnear = 0;
            rays[k].tfar = rs_v3_dot(d, n) > 0 ? INFINITY : 0;   /* below the horizon: no ray */
            s->pixels[k] = (uint32_t)pix;
        }
        if (M) rs_scene_occluded(g->scene, rays, occl, (size_t)M);
        for (int k = 0; k < M; k++) {
            double cosn = rs_v3_dot(rays[k].dir, n);
            if (cosn <= 0 || occl[k]) continue;
            size_t pix = s->pixels[k];
            double lum = rs_skyenv_luminance(env->radiance + 3 * pix), wgt;
            if (pass)                                        /* L cos / pdf / Ns, pdf = lum / power */
                wgt = cosn * env->sun_power / (lum * Ns);
            else                                             /* balance heuristic, already / Ne */
                wgt = cosn / (Nc * cosn / M_PI + Ne * rs_skyenv_pdf(env, pix));
            add_sky(env, pix, wgt, out);
        }
    }

    /* K row: merge hits per facet j (sorted, so the file does not depend on thread timing). */
    qsort(refs, (size_t)nrefs, sizeof *refs, cmp_hit);
    if (nrefs) {
        out->entries = malloc((size_t)nrefs * sizeof *out->entries);
        if (!out->entries) return -1;
    }
    for (int k = 0; k < nrefs; k++) {
        rs_kentry *e = out->nentries ? &out->entries[out->nentries - 1] : NULL;
        if (!e || e->col != refs[k].face) {
            e = &out->entries[out->nentries++];
            e->col = refs[k].face;
            e->k = e->k_unseen = 0;
        }
        e->k += (float)w;
        if (refs[k].unseen) e->k_unseen += (float)w;
    }
    return 0;
}


/* scenegen: procedural building scenes (see scenegen.h). The scene is a list of rectangles
 * (quads), each subdivided into square-ish cells of two triangles; one cell size serves all. */
#include "bench/scenegen.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/sampling.h"

typedef struct {
    rs_v3 o, e1, e2; /* corner and edges; the normal is along e1 x e2 */
    uint32_t part;
    double coarse; /* cell size multiple (the far ground is meshed coarser) */
} quad;

typedef struct {
    quad *q;
    size_t n, cap;
    uint32_t nparts;
} quad_list;

static int push(quad_list *l, rs_v3 o, rs_v3 e1, rs_v3 e2, uint32_t part, double coarse)
{
    if (l->n == l->cap) {
        size_t cap = l->cap ? 2 * l->cap : 256;
        quad *q = realloc(l->q, cap * sizeof *q);
        if (!q) return -1;
        l->q = q;
        l->cap = cap;
    }
    l->q[l->n++] = (quad){o, e1, e2, part, coarse};
    return 0;
}

enum { NX = 1, PX = 2, NY = 4, PY = 8, NZ = 16, PZ = 32, ALL = 63 };

/* Axis-aligned box [lo, hi]: the faces in `faces` (bit mask), outward, or inward (facing the
 * inside, for a courtyard's yard walls). */
static int box(quad_list *l, rs_v3 lo, rs_v3 hi, int faces, int inward, uint32_t part)
{
    rs_v3 d = rs_v3_sub(hi, lo);
    rs_v3 ex = {d.x, 0, 0}, ey = {0, d.y, 0}, ez = {0, 0, d.z};
    const struct {
        int bit;
        rs_v3 o, a, b;
    } f[6] = {
        {NZ, lo, ey, ex}, {PZ, rs_v3_add(lo, ez), ex, ey}, {NY, lo, ex, ez}, {PY, rs_v3_add(lo, ey), ez, ex},
        {NX, lo, ez, ey}, {PX, rs_v3_add(lo, ex), ey, ez},
    };
    for (int k = 0; k < 6; k++) {
        if (!(faces & f[k].bit)) continue;
        if (push(l, f[k].o, inward ? f[k].b : f[k].a, inward ? f[k].a : f[k].b, part, 1) != 0) return -1;
    }
    return 0;
}

static double urand(uint32_t seed, uint32_t k)
{
    return rs_hash_combine(seed, k) / 4294967296.0;
}

/* A facade at x = x0 facing dir (+1 or -1) along y in [y0, y1]: fins (niches between them)
 * under an overhanging slab. Parts: fins and slab each their own. */
static int facade(quad_list *l, double x0, int dir, double y0, double y1, double slab_z)
{
    double depth = 1.0, thick = 0.3, sdepth = 1.6;
    uint32_t fin_part = l->nparts++, slab_part = l->nparts++;
    int wall = dir > 0 ? NX : PX; /* the fin face that touches the wall is left out */
    for (double y = y0 + 1.0; y + thick < y1 - 0.5; y += 3.0) {
        rs_v3 lo = {dir > 0 ? x0 : x0 - depth, y, 0}, hi = {dir > 0 ? x0 + depth : x0, y + thick, slab_z};
        if (box(l, lo, hi, ALL & ~wall & ~NZ & ~PZ, 0, fin_part) != 0) return -1;
    }
    rs_v3 lo = {dir > 0 ? x0 : x0 - sdepth, y0, slab_z}, hi = {dir > 0 ? x0 + sdepth : x0, y1, slab_z + thick};
    return box(l, lo, hi, ALL & ~wall, 0, slab_part);
}

static int layout(quad_list *l, uint32_t seed, rs_v3 *camera)
{
    const double pitch = 26, half = 8; /* 16 m blocks, 10 m streets */
    l->nparts = 1;                     /* part 0: the ground */
    if (push(l, (rs_v3){-55, -55, 0}, (rs_v3){110, 0, 0}, (rs_v3){0, 110, 0}, 0, 2) != 0) return -1;
    for (int j = -1; j <= 1; j++)
        for (int i = -1; i <= 1; i++) {
            uint32_t k = (uint32_t)((j + 1) * 3 + (i + 1));
            double cx = i * pitch, cy = j * pitch, h = 8 + 12 * urand(seed, 10 * k);
            int type = (i == 0 && j == 0) || (i == 1 && j == 0) ? 2 : (int)(k % 3);
            rs_v3 lo = {cx - half, cy - half, 0}, hi = {cx + half, cy + half, h};
            if (type == 1) { /* courtyard: outer walls, yard walls, roof ring */
                double in = 4;
                uint32_t p = l->nparts++;
                if (box(l, lo, hi, NX | PX | NY | PY, 0, p) != 0 ||
                    box(l, (rs_v3){cx - in, cy - in, 0}, (rs_v3){cx + in, cy + in, h}, NX | PX | NY | PY, 1, p) != 0 ||
                    push(l, (rs_v3){cx - half, cy - half, h}, (rs_v3){2 * half, 0, 0}, (rs_v3){0, half - in, 0}, p,
                         1) ||
                    push(l, (rs_v3){cx - half, cy + in, h}, (rs_v3){2 * half, 0, 0}, (rs_v3){0, half - in, 0}, p, 1) ||
                    push(l, (rs_v3){cx - half, cy - in, h}, (rs_v3){half - in, 0, 0}, (rs_v3){0, 2 * in, 0}, p, 1) ||
                    push(l, (rs_v3){cx + in, cy - in, h}, (rs_v3){half - in, 0, 0}, (rs_v3){0, 2 * in, 0}, p, 1))
                    return -1;
                continue;
            }
            if (box(l, lo, hi, ALL & ~NZ, 0, l->nparts++) != 0) return -1;
            if (type == 2 &&
                (facade(l, cx + half, 1, cy - half, cy + half, 4) != 0 ||
                 facade(l, cx - half, -1, cy - half, cy + half, 4) != 0))
                return -1;
            if (type == 0 &&
                box(l, (rs_v3){cx - 3, cy - 3, h}, (rs_v3){cx + 3, cy + 3, h + 3}, ALL & ~NZ, 0, l->nparts++) != 0)
                return -1; /* a roof structure: roof facets beside it see a wall */
        }
    *camera = (rs_v3){pitch / 2, -3, 1.6}; /* in the street between the two facades with niches */
    return 0;
}

static size_t cells(double len, double size)
{
    return (size_t)fmax(1, ceil(len / size - 1e-9));
}

static size_t count_facets(const quad_list *l, double size)
{
    size_t n = 0;
    for (size_t k = 0; k < l->n; k++) {
        double s = size * l->q[k].coarse;
        n += 2 * cells(rs_v3_len(l->q[k].e1), s) * cells(rs_v3_len(l->q[k].e2), s);
    }
    return n;
}

rs_bench_scene *rs_bench_scene_new(size_t target_facets, uint32_t seed)
{
    quad_list l = {0};
    rs_bench_scene *s = calloc(1, sizeof *s);
    if (!s || layout(&l, seed, &s->camera) != 0) goto fail;
    /* Cell size by bisection on a log scale: the count falls as the size grows. */
    double lo = 1e-3, hi = 200;
    for (int it = 0; it < 60; it++) {
        double mid = sqrt(lo * hi);
        if (count_facets(&l, mid) > target_facets)
            lo = mid;
        else
            hi = mid;
    }
    size_t nf = count_facets(&l, hi), nv = 0;
    for (size_t k = 0; k < l.n; k++) {
        double c = hi * l.q[k].coarse;
        nv += (cells(rs_v3_len(l.q[k].e1), c) + 1) * (cells(rs_v3_len(l.q[k].e2), c) + 1);
    }
    s->mesh = rs_mesh_new(nv, nf);
    s->part = malloc(nf * sizeof *s->part);
    s->nparts = l.nparts;
    s->albedo = malloc(3 * s->nparts * sizeof *s->albedo);
    if (!s->mesh || !s->part || !s->albedo) goto fail;
    size_t v = 0, f = 0;
    for (size_t k = 0; k < l.n; k++) {
        const quad *q = &l.q[k];
        int nu = (int)cells(rs_v3_len(q->e1), hi * q->coarse), nw = (int)cells(rs_v3_len(q->e2), hi * q->coarse);
        size_t base = v;
        for (int b = 0; b <= nw; b++)
            for (int a = 0; a <= nu; a++) {
                rs_v3 p =
                    rs_v3_add(q->o, rs_v3_add(rs_v3_scale(q->e1, (double)a / nu), rs_v3_scale(q->e2, (double)b / nw)));
                float *out = s->mesh->verts + 3 * v++;
                out[0] = (float)p.x, out[1] = (float)p.y, out[2] = (float)p.z;
            }
        for (int b = 0; b < nw; b++)
            for (int a = 0; a < nu; a++) {
                uint32_t i00 = (uint32_t)(base + (size_t)b * (nu + 1) + a), i10 = i00 + 1, i01 = i00 + (uint32_t)nu + 1,
                         i11 = i01 + 1;
                uint32_t *t = s->mesh->tris + 3 * f;
                t[0] = i00, t[1] = i10, t[2] = i11, t[3] = i00, t[4] = i11, t[5] = i01;
                s->part[f++] = q->part;
                s->part[f++] = q->part;
            }
    }
    /* Albedo per part: ground a neutral grey, the rest coloured, within [0.15, 0.8]. */
    s->albedo[0] = 0.30, s->albedo[1] = 0.28, s->albedo[2] = 0.25;
    for (size_t p = 1; p < s->nparts; p++)
        for (int ch = 0; ch < 3; ch++)
            s->albedo[3 * p + ch] = 0.15 + 0.65 * urand(seed ^ 0xa1bedu, (uint32_t)(3 * p + ch));
    free(l.q);
    return s;
fail:
    free(l.q);
    rs_bench_scene_free(s);
    return NULL;
}

void rs_bench_scene_free(rs_bench_scene *s)
{
    if (!s) return;
    rs_mesh_free(s->mesh);
    free(s->part);
    free(s->albedo);
    free(s);
}

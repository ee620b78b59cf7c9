/* meshgen: procedural test meshes (see meshgen.h). */
#include "tests/meshgen.h"

#include <math.h>
#include <stdlib.h>
#include "common/ply.h"
#include "tests/testutil.h"

rs_meshgen rs_meshgen_new(size_t max_verts, size_t max_faces)
{
    rs_meshgen g = {rs_mesh_new(max_verts, max_faces), 0, 0};
    return g;
}

size_t rs_meshgen_rect(rs_meshgen *g, rs_v3 o, rs_v3 e1, rs_v3 e2, int nu, int nv)
{
    size_t base = g->nv, first = g->nf;
    for (int j = 0; j <= nv; j++)
        for (int i = 0; i <= nu; i++) {
            rs_v3 p = rs_v3_add(o, rs_v3_add(rs_v3_scale(e1, (double)i / nu), rs_v3_scale(e2, (double)j / nv)));
            float *v = g->m->verts + 3 * g->nv++;
            v[0] = (float)p.x;
            v[1] = (float)p.y;
            v[2] = (float)p.z;
        }
    for (int j = 0; j < nv; j++)
        for (int i = 0; i < nu; i++) {
            uint32_t a = (uint32_t)(base + (size_t)j * (nu + 1) + i), b = a + 1, c = a + (uint32_t)nu + 1, d = c + 1;
            uint32_t *t = g->m->tris + 3 * g->nf;
            t[0] = a, t[1] = b, t[2] = d;
            t[3] = a, t[4] = d, t[5] = c;
            g->nf += 2;
        }
    return first;
}

void rs_meshgen_box(rs_meshgen *g, rs_v3 lo, rs_v3 hi, int n, int inward)
{
    rs_v3 d = rs_v3_sub(hi, lo);
    rs_v3 ex = {d.x, 0, 0}, ey = {0, d.y, 0}, ez = {0, 0, d.z};
    /* Outward faces: e1 x e2 points out. Inward: swap e1 and e2. */
    struct {
        rs_v3 o, a, b;
    } f[6] = {
        {lo, ey, ex},                /* bottom, -z */
        {rs_v3_add(lo, ez), ex, ey}, /* top, +z */
        {lo, ex, ez},                /* front, -y */
        {rs_v3_add(lo, ey), ez, ex}, /* back, +y */
        {lo, ez, ey},                /* left, -x */
        {rs_v3_add(lo, ex), ey, ez}, /* right, +x */
    };
    for (int k = 0; k < 6; k++) {
        if (inward)
            rs_meshgen_rect(g, f[k].o, f[k].b, f[k].a, n, n);
        else
            rs_meshgen_rect(g, f[k].o, f[k].a, f[k].b, n, n);
    }
}

rs_mesh *rs_meshgen_done(rs_meshgen *g)
{
    g->m->nverts = g->nv;
    g->m->nfaces = g->nf;
    return g->m;
}

void rs_meshgen_write(const rs_mesh *m, const char *path)
{
    rs_ply *ply = rs_ply_new();
    rs_mesh_to_ply(m, ply);
    rs_err err;
    assert_int_equal(rs_ply_write(ply, path, 1, &err), 0);
    rs_ply_free(ply);
}

int rs_meshgen_wall_ground_sees(const rs_meshgen_wall_ground *s, rs_v3 o, rs_v3 d)
{
    double tw = d.x > 0 ? (s->wall_x - o.x) / d.x : INFINITY, tg = d.z < 0 ? -o.z / d.z : INFINITY;
    if (tw < tg) {
        rs_v3 p = rs_v3_add(o, rs_v3_scale(d, tw));
        if (p.y >= s->wy0 && p.y <= s->wy1 && p.z >= 0 && p.z <= s->wall_h) return 2;
    }
    if (isfinite(tg)) {
        rs_v3 p = rs_v3_add(o, rs_v3_scale(d, tg));
        if (p.x >= s->gx0 && p.x <= s->gx1 && p.y >= s->gy0 && p.y <= s->gy1) return 1;
    }
    return 0;
}

/* freespace_faces: the occluder faces of a free-space grid (freespace.h): known/unknown faces
 * merged greedily into rectangles per grid plane, and each rectangle's proxy facet, the nearest
 * scanned one facing the same way by a breadth-first search from those facets' cells. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "meshing/freespace.h"

/* label[] := every cell's nearest facet among those facing[f] & bit marks (every facet when
 * facing is NULL), UINT32_MAX where none is reachable: those facets' own cells, spread through the
 * grid in breadth-first order (6-neighbours) with queue[] (ncells entries) as scratch; dist[] (when
 * not NULL): the steps taken (a city-block distance in cells, 254 at most, 255 unreached).
 * Returns the facets that seeded it. */
static size_t spread_labels(const rs_freespace *fs, const rs_mesh *m, const uint8_t *facing, uint8_t bit,
                            uint32_t *label, uint32_t *queue, uint8_t *dist)
{
    size_t n = fs->ncells;
    memset(label, 0xff, n * sizeof *label);
    uint8_t *use = NULL;
    if (facing) {
        if (!(use = malloc(m->nfaces ? m->nfaces : 1))) return SIZE_MAX;
        for (size_t f = 0; f < m->nfaces; f++) use[f] = (facing[f] & bit) != 0;
    }
    size_t seeds = rs_freespace_label(fs, m, use, label);
    free(use);
    size_t head = 0, tail = 0;
    if (dist) memset(dist, 255, n);
    for (size_t idx = 0; idx < n; idx++)
        if (label[idx] != UINT32_MAX) {
            queue[tail++] = (uint32_t)idx;
            if (dist) dist[idx] = 0;
        }
    size_t sx = 1, sy = (size_t)fs->n[0], sz = (size_t)fs->n[0] * fs->n[1];
    while (head < tail) {
        size_t idx = queue[head++];
        int i = (int)(idx % sy), j = (int)((idx / sy) % fs->n[1]), k = (int)(idx / sz);
        size_t nb[6];
        int cnt = 0;
        if (i > 0) nb[cnt++] = idx - sx;
        if (i + 1 < fs->n[0]) nb[cnt++] = idx + sx;
        if (j > 0) nb[cnt++] = idx - sy;
        if (j + 1 < fs->n[1]) nb[cnt++] = idx + sy;
        if (k > 0) nb[cnt++] = idx - sz;
        if (k + 1 < fs->n[2]) nb[cnt++] = idx + sz;
        for (int q = 0; q < cnt; q++)
            if (label[nb[q]] == UINT32_MAX) {
                label[nb[q]] = label[idx];
                if (dist) dist[nb[q]] = dist[idx] < 254 ? (uint8_t)(dist[idx] + 1) : 254;
                queue[tail++] = (uint32_t)nb[q];
            }
    }
    return seeds;
}

/* facing[f]: bit 2 ax + (sign < 0) set when facet f's normal lies within RS_FS_PROXY_COS of the
 * axis direction sign e_ax, i.e. when f may stand for an unseen surface facing that way. NULL when
 * out of memory. */
static uint8_t *facing_bits(const rs_mesh *m)
{
    uint8_t *facing = calloc(m->nfaces ? m->nfaces : 1, 1);
    if (!facing) return NULL;
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 c, n;
        double area;
        rs_mesh_face(m, f, &c, &n, &area);
        double nv[3] = {n.x, n.y, n.z};
        for (int a = 0; a < 3; a++) {
            if (nv[a] > RS_FS_PROXY_COS) facing[f] |= (uint8_t)(1 << (2 * a));
            if (nv[a] < -RS_FS_PROXY_COS) facing[f] |= (uint8_t)(1 << (2 * a + 1));
        }
    }
    return facing;
}

/* Marks behind[] the cells behind facet f: those whose centre lies in the prism behind its
 * triangle (the side the scanner did not see), within depth of its plane. Centres, not every cell
 * the prism touches, so that a facet whose edge or back lies on a cell boundary does not claim
 * the cell beyond it. */
static void mark_behind(const rs_freespace *fs, const rs_mesh *m, size_t f, double depth, uint8_t *behind)
{
    rs_v3 c, n, v[3];
    double area;
    rs_mesh_face(m, f, &c, &n, &area);
    if (!(area > 0) || !rs_v3_finite(n)) return;
    for (int k = 0; k < 3; k++) v[k] = rs_mesh_vert(m, m->tris[3 * f + k]);
    double lo[3], hi[3];
    for (int a = 0; a < 3; a++) {
        double nv = a == 0 ? n.x : a == 1 ? n.y : n.z;
        lo[a] = INFINITY, hi[a] = -INFINITY;
        for (int k = 0; k < 3; k++) {
            double p = a == 0 ? v[k].x : a == 1 ? v[k].y : v[k].z;
            lo[a] = fmin(lo[a], fmin(p, p - nv * depth));
            hi[a] = fmax(hi[a], fmax(p, p - nv * depth));
        }
    }
    int i0[3], i1[3];
    for (int a = 0; a < 3; a++) {
        i0[a] = (int)fmax(0, floor((lo[a] - fs->lo[a]) / fs->cell - 0.5));
        i1[a] = (int)fmin(fs->n[a] - 1, ceil((hi[a] - fs->lo[a]) / fs->cell - 0.5));
    }
    rs_v3 e1 = rs_v3_sub(v[1], v[0]), e2 = rs_v3_sub(v[2], v[0]);
    double d11 = rs_v3_dot(e1, e1), d12 = rs_v3_dot(e1, e2), d22 = rs_v3_dot(e2, e2), den = d11 * d22 - d12 * d12;
    if (!(den > 0)) return;
    for (int k = i0[2]; k <= i1[2]; k++)
        for (int j = i0[1]; j <= i1[1]; j++)
            for (int i = i0[0]; i <= i1[0]; i++) {
                rs_v3 q = rs_v3_make(fs->lo[0] + (i + 0.5) * fs->cell, fs->lo[1] + (j + 0.5) * fs->cell,
                                     fs->lo[2] + (k + 0.5) * fs->cell);
                rs_v3 w = rs_v3_sub(q, v[0]);
                double d = -rs_v3_dot(w, n); /* depth behind the plane */
                if (!(d > 0 && d <= depth)) continue;
                double w1 = rs_v3_dot(w, e1), w2 = rs_v3_dot(w, e2);
                double s = (d22 * w1 - d12 * w2) / den, t = (d11 * w2 - d12 * w1) / den;
                if (s >= -1e-9 && t >= -1e-9 && s + t <= 1 + 1e-9)
                    behind[((size_t)k * fs->n[1] + (size_t)j) * fs->n[0] + (size_t)i] = 1;
            }
}

/* 1 when unknown cell (i, j, k) closes a gap along an axis: within span cells each way, before
 * any free cell or the grid's edge, a cell behind a facet. */
static int in_gap(const rs_freespace *fs, const uint8_t *behind, const int c[3], int span)
{
    for (int a = 0; a < 3; a++) {
        int ends = 0;
        for (int dir = -1; dir <= 1; dir += 2)
            for (int s = 1; s <= span; s++) {
                int q[3] = {c[0], c[1], c[2]};
                q[a] += dir * s;
                if (q[a] < 0 || q[a] >= fs->n[a]) break;
                size_t idx = ((size_t)q[2] * fs->n[1] + (size_t)q[1]) * fs->n[0] + (size_t)q[0];
                if (rs_freespace_cell(fs, q[0], q[1], q[2]) == RS_FS_FREE) break;
                if (behind[idx]) {
                    ends++;
                    break;
                }
            }
        if (ends == 2) return 1;
    }
    return 0;
}

/* Marks dist[] 255 (open) for the unknown cells that are neither behind a facet of m nor in a gap
 * between such cells (RS_FS_KEEP_BEHIND). -1 out of memory. */
static int open_unbacked(const rs_freespace *fs, const rs_mesh *m, double depth, uint8_t *dist)
{
    uint8_t *behind = calloc(fs->ncells, 1);
    if (!behind) return -1;
    for (size_t f = 0; f < m->nfaces; f++) mark_behind(fs, m, f, depth, behind);
    int span = (int)floor(depth / fs->cell + 1e-9);
    for (int k = 0; k < fs->n[2]; k++)
        for (int j = 0; j < fs->n[1]; j++)
            for (int i = 0; i < fs->n[0]; i++) {
                size_t idx = ((size_t)k * fs->n[1] + (size_t)j) * fs->n[0] + (size_t)i;
                int c[3] = {i, j, k};
                if (behind[idx] || dist[idx] == 255 || rs_freespace_cell(fs, i, j, k) != RS_FS_UNKNOWN) continue;
                if (!in_gap(fs, behind, c, span)) dist[idx] = 255;
            }
    free(behind);
    return 0;
}

typedef struct face_list {
    float *verts;
    uint32_t *proxy;
    size_t nrect, cap;
} face_list;

/* Appends the rectangle [u0, u1) x [v0, v1) of cells in the plane ax = p (cell units) as two
 * triangles facing sign along ax, with proxy pr. */
static int add_rect(face_list *fl, const rs_freespace *fs, int ax, int p, int u0, int u1, int v0, int v1, int sign,
                    uint32_t pr)
{
    if (fl->nrect == fl->cap) {
        size_t cap = fl->cap ? 2 * fl->cap : 1024;
        float *v = realloc(fl->verts, cap * 12 * sizeof *v);
        if (!v) return -1;
        fl->verts = v;
        uint32_t *q = realloc(fl->proxy, cap * 2 * sizeof *q);
        if (!q) return -1;
        fl->proxy = q;
        fl->cap = cap;
    }
    int au = (ax + 1) % 3, av = (ax + 2) % 3;
    int cu[4] = {u0, u1, u1, u0}, cv[4] = {v0, v0, v1, v1};
    float *out = fl->verts + 12 * fl->nrect;
    for (int c = 0; c < 4; c++) {
        int k = sign > 0 ? c : (4 - c) % 4; /* (u, v, ax) is right-handed: u, v ccw faces +ax */
        out[3 * c + ax] = (float)(fs->lo[ax] + p * fs->cell);
        out[3 * c + au] = (float)(fs->lo[au] + cu[k] * fs->cell);
        out[3 * c + av] = (float)(fs->lo[av] + cv[k] * fs->cell);
    }
    fl->proxy[2 * fl->nrect] = fl->proxy[2 * fl->nrect + 1] = pr;
    fl->nrect++;
    return 0;
}

static int known(const rs_freespace *fs, int c[3])
{
    return rs_freespace_cell(fs, c[0], c[1], c[2]) != RS_FS_UNKNOWN;
}

/* The faces of one plane ax = p (between cells p - 1 and p) that look toward sign e_ax:
 * mask[u + nu v] = +1 where the cell above is known and the one below unknown (the face looks up,
 * +ax), -1 the other way round, 0 also where it is not sign; then greedy rectangles, each with the
 * label (the proxy) of the unknown cell at its centre. */
static int plane_faces(const rs_freespace *fs, const uint32_t *label, int ax, int p, int sign, int8_t *mask,
                       face_list *fl)
{
    int au = (ax + 1) % 3, av = (ax + 2) % 3, nu = fs->n[au], nv = fs->n[av];
    int any = 0;
    for (int v = 0; v < nv; v++)
        for (int u = 0; u < nu; u++) {
            int lo[3], hi[3];
            lo[ax] = p - 1, hi[ax] = p;
            lo[au] = hi[au] = u;
            lo[av] = hi[av] = v;
            int kl = known(fs, lo), kh = known(fs, hi);
            int8_t sg = (int8_t)(kl == kh ? 0 : kh ? 1 : -1);
            mask[u + (size_t)nu * v] = sg == sign ? sg : 0;
            any |= sg == sign;
        }
    if (!any) return 0;
    for (int v = 0; v < nv; v++)
        for (int u = 0; u < nu; u++) {
            int8_t s = mask[u + (size_t)nu * v];
            if (!s) continue;
            int u1 = u + 1, v1 = v + 1;
            while (u1 < nu && mask[u1 + (size_t)nu * v] == s) u1++;
            for (int ok = 1; ok && v1 < nv; v1 += ok)
                for (int x = u; x < u1; x++)
                    if (mask[x + (size_t)nu * v1] != s) ok = 0;
            for (int y = v; y < v1; y++) memset(mask + u + (size_t)nu * y, 0, (size_t)(u1 - u));
            int c[3]; /* the unknown cell at the rectangle's centre */
            c[ax] = s > 0 ? p - 1 : p;
            c[au] = (u + u1 - 1) / 2;
            c[av] = (v + v1 - 1) / 2;
            size_t idx = ((size_t)c[2] * fs->n[1] + (size_t)c[1]) * fs->n[0] + (size_t)c[0];
            uint32_t pr = label[idx];
            if (pr == UINT32_MAX) continue; /* no facet at all: nothing to stand for it */
            if (add_rect(fl, fs, ax, p, u, u1, v, v1, s, pr) != 0) return -1;
        }
    return 0;
}

int rs_freespace_occluders(rs_freespace *fs, const rs_mesh *m, double depth, rs_fs_keep keep, rs_mesh **occ,
                           uint32_t **proxy, rs_err *err)
{
    *occ = NULL;
    *proxy = NULL;
    uint8_t *dist = malloc(fs->ncells), *facing = facing_bits(m);
    uint32_t *label = malloc(fs->ncells * sizeof *label), *queue = malloc(fs->ncells * sizeof *queue);
    int maxn = fs->n[0] * fs->n[1] > fs->n[1] * fs->n[2] ? fs->n[0] * fs->n[1] : fs->n[1] * fs->n[2];
    if (fs->n[0] * fs->n[2] > maxn) maxn = fs->n[0] * fs->n[2];
    int8_t *mask = malloc((size_t)maxn);
    face_list fl = {0};
    int rc = -1;
    if (!label || !queue || !dist || !facing || !mask) goto oom;
    if (spread_labels(fs, m, NULL, 0, label, queue, dist) == SIZE_MAX) goto oom;
    if (keep == RS_FS_KEEP_BEHIND && open_unbacked(fs, m, depth, dist) != 0) goto oom;
    /* Unknown space farther than depth from every facet (or not backed by one) is taken as open. */
    double dmax = depth / fs->cell;
    fs->opened = 0;
    for (size_t idx = 0; idx < fs->ncells; idx++)
        if (dist[idx] > dmax && (fs->bits[idx >> 2] >> (2 * (idx & 3)) & 3) == 0) {
            fs->bits[idx >> 2] |= (uint8_t)(1 << (2 * (idx & 3)));
            fs->opened++;
        }
    /* Per face direction, the proxies: the nearest facets facing that way (the nearest of all
     * when none does). */
    for (int ax = 0; ax < 3; ax++)
        for (int sign = 1; sign >= -1; sign -= 2) {
            uint8_t bit = (uint8_t)(1 << (2 * ax + (sign < 0)));
            size_t seeds = spread_labels(fs, m, facing, bit, label, queue, NULL);
            if (seeds == 0) seeds = spread_labels(fs, m, NULL, 0, label, queue, NULL);
            if (seeds == SIZE_MAX) goto oom;
            for (int p = 1; p < fs->n[ax]; p++)
                if (plane_faces(fs, label, ax, p, sign, mask, &fl) != 0) goto oom;
        }
    if (fl.nrect) {
        rs_mesh *o = rs_mesh_new(4 * fl.nrect, 2 * fl.nrect);
        if (!o) goto oom;
        memcpy(o->verts, fl.verts, 12 * fl.nrect * sizeof(float));
        for (size_t r = 0; r < fl.nrect; r++) {
            uint32_t b = (uint32_t)(4 * r), t[6] = {b, b + 1, b + 2, b, b + 2, b + 3};
            memcpy(o->tris + 6 * r, t, sizeof t);
        }
        *occ = o;
        *proxy = fl.proxy;
        fl.proxy = NULL;
    }
    rc = 0;
    goto out;
oom:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the occluders of %zu cells", fs->ncells);
out:
    free(label);
    free(queue);
    free(dist);
    free(facing);
    free(mask);
    free(fl.verts);
    free(fl.proxy);
    return rc;
}

/* freespace: the 2-bit grid of free and occupied space, its 3D-DDA carving and the occluder
 * faces between known and unknown cells (see freespace.h). */
#include "meshing/freespace.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

static size_t cell_index(const rs_freespace *fs, int i, int j, int k)
{
    return ((size_t)k * fs->n[1] + (size_t)j) * fs->n[0] + (size_t)i;
}

static int bits_at(const rs_freespace *fs, size_t idx)
{
    return (fs->bits[idx >> 2] >> (2 * (idx & 3))) & 3;
}

static void set_bits(rs_freespace *fs, size_t idx, int b)
{
    uint8_t mask = (uint8_t)(b << (2 * (idx & 3)));
    uint8_t *byte = &fs->bits[idx >> 2];
    if ((__atomic_load_n(byte, __ATOMIC_RELAXED) & mask) != mask) __atomic_fetch_or(byte, mask, __ATOMIC_RELAXED);
}

int rs_freespace_cell(const rs_freespace *fs, int i, int j, int k)
{
    int b = bits_at(fs, cell_index(fs, i, j, k));
    return b & 2 ? RS_FS_OCCUPIED : b & 1 ? RS_FS_FREE : RS_FS_UNKNOWN;
}

/* The cell of p, or 0 when p lies outside the grid. */
static int locate(const rs_freespace *fs, rs_v3 p, int c[3])
{
    double q[3] = {p.x, p.y, p.z};
    for (int a = 0; a < 3; a++) {
        double g = floor((q[a] - fs->lo[a]) / fs->cell);
        if (!(g >= 0 && g < fs->n[a])) return 0;
        c[a] = (int)g;
    }
    return 1;
}

int rs_freespace_state(const rs_freespace *fs, rs_v3 p)
{
    int c[3];
    if (!locate(fs, p, c)) return RS_FS_FREE;
    return rs_freespace_cell(fs, c[0], c[1], c[2]);
}

/* Marks the cells of facet f's triangle (sampled at a third of a cell) with b, or, with label
 * non-NULL, writes f into label[] of each. */
static void sample_facet(rs_freespace *fs, const rs_mesh *m, size_t f, uint32_t *label)
{
    rs_v3 v[3];
    for (int k = 0; k < 3; k++) v[k] = rs_mesh_vert(m, m->tris[3 * f + k]);
    double e = fmax(rs_v3_len(rs_v3_sub(v[1], v[0])),
                    fmax(rs_v3_len(rs_v3_sub(v[2], v[1])), rs_v3_len(rs_v3_sub(v[0], v[2]))));
    int steps = (int)ceil(e / (fs->cell / 3));
    if (steps < 1) steps = 1;
    if (steps > 4096) steps = 4096;
    for (int i = 0; i <= steps; i++)
        for (int j = 0; i + j <= steps; j++) {
            double s = (double)i / steps, t = (double)j / steps;
            rs_v3 p = rs_v3_add(
                v[0], rs_v3_add(rs_v3_scale(rs_v3_sub(v[1], v[0]), s), rs_v3_scale(rs_v3_sub(v[2], v[0]), t)));
            int c[3];
            if (!locate(fs, p, c)) continue;
            size_t idx = cell_index(fs, c[0], c[1], c[2]);
            if (label)
                label[idx] = (uint32_t)f;
            else
                set_bits(fs, idx, 2);
        }
}

int rs_freespace_init(rs_freespace *fs, const rs_mesh *m, const rs_freespace_opts *opts, rs_err *err)
{
    memset(fs, 0, sizeof *fs);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < m->nverts; v++)
        for (int a = 0; a < 3; a++) {
            lo[a] = fmin(lo[a], m->verts[3 * v + a]);
            hi[a] = fmax(hi[a], m->verts[3 * v + a]);
        }
    if (!(opts->cell > 0) || !(hi[0] >= lo[0]))
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "free-space grid: no vertices or a cell of %g m", opts->cell);
    double cell = opts->cell, size = 0;
    for (;;) {
        size = 1;
        for (int a = 0; a < 3; a++) {
            double top = hi[a] + (a < 2 ? opts->margin : 1e-4 * cell); /* nothing above the model's top */
            fs->n[a] = (int)ceil((top - (lo[a] - opts->margin)) / cell);
            if (fs->n[a] < 1) fs->n[a] = 1;
            fs->lo[a] = a < 2 ? lo[a] - opts->margin : top - fs->n[a] * cell;
            size *= fs->n[a];
        }
        if (size <= (double)opts->max_cells) break;
        cell *= 1.2599210498948732; /* 2^(1/3): half the cells */
    }
    fs->cell = cell;
    fs->ncells = (size_t)size;
    if (!(fs->bits = calloc((fs->ncells + 3) / 4, 1)))
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for a free-space grid of %zu cells", fs->ncells);
    for (size_t f = 0; f < m->nfaces; f++) sample_facet(fs, m, f, NULL);
    return 0;
}

size_t rs_freespace_label(const rs_freespace *fs, const rs_mesh *m, const uint8_t *use, uint32_t *label)
{
    size_t n = 0;
    for (size_t f = 0; f < m->nfaces; f++)
        if (!use || use[f]) sample_facet((rs_freespace *)fs, m, f, label), n++;
    return n;
}

void rs_freespace_release(rs_freespace *fs)
{
    free(fs->bits);
    memset(fs, 0, sizeof *fs);
}

/* The parameter range [t0, t1] of p(t) = a + t d inside the grid's box (slab test); 0 when the
 * line misses it. */
static int clip_box(const rs_freespace *fs, const double a[3], const double d[3], double *t0, double *t1)
{
    for (int k = 0; k < 3; k++) {
        double lo = fs->lo[k], hi = fs->lo[k] + fs->n[k] * fs->cell;
        if (d[k] == 0) {
            if (a[k] < lo || a[k] >= hi) return 0;
            continue;
        }
        double ta = (lo - a[k]) / d[k], tb = (hi - a[k]) / d[k];
        if (ta > tb) {
            double x = ta;
            ta = tb;
            tb = x;
        }
        *t0 = fmax(*t0, ta);
        *t1 = fmin(*t1, tb);
    }
    return *t0 < *t1;
}

void rs_freespace_carve(rs_freespace *fs, rs_v3 pa, rs_v3 pb, int to_edge)
{
    double a[3] = {pa.x, pa.y, pa.z}, d[3] = {pb.x - pa.x, pb.y - pa.y, pb.z - pa.z};
    double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(len > 0) || !isfinite(len)) return;
    for (int k = 0; k < 3; k++) d[k] /= len;
    double t0 = 0, t1 = to_edge ? INFINITY : len - 0.5 * fs->cell;
    if (!(t1 > 0) || !clip_box(fs, a, d, &t0, &t1)) return;
    /* Amanatides and Woo: the cell at t0 (nudged inside), then one axis step at a time. */
    int c[3], step[3];
    double tmax[3], tdelta[3];
    for (int k = 0; k < 3; k++) {
        double g = (a[k] + (t0 + 1e-9 * fs->cell) * d[k] - fs->lo[k]) / fs->cell;
        c[k] = (int)floor(g);
        if (c[k] < 0) c[k] = 0;
        if (c[k] >= fs->n[k]) c[k] = fs->n[k] - 1;
        step[k] = d[k] > 0 ? 1 : -1;
        if (d[k] == 0) {
            tmax[k] = tdelta[k] = INFINITY;
        } else {
            double edge = fs->lo[k] + (c[k] + (d[k] > 0)) * fs->cell;
            tmax[k] = (edge - a[k]) / d[k];
            tdelta[k] = fs->cell / fabs(d[k]);
        }
    }
    double t = t0;
    size_t visited = 0;
    while (t < t1) {
        set_bits(fs, cell_index(fs, c[0], c[1], c[2]), 1);
        visited++;
        int k = tmax[0] < tmax[1] ? (tmax[0] < tmax[2] ? 0 : 2) : (tmax[1] < tmax[2] ? 1 : 2);
        t = tmax[k];
        tmax[k] += tdelta[k];
        c[k] += step[k];
        if (c[k] < 0 || c[k] >= fs->n[k]) break;
    }
    (void)visited;
}

void rs_freespace_count(const rs_freespace *fs, rs_freespace_counts *c)
{
    memset(c, 0, sizeof *c);
    for (size_t idx = 0; idx < fs->ncells; idx++) {
        int b = bits_at(fs, idx);
        if (b & 2)
            c->occupied++;
        else if (b & 1)
            c->free++;
        else
            c->unknown++;
    }
}

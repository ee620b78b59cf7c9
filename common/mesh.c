/* mesh: indexed triangle meshes (mesh.h): life cycle, conversion from and to PLY, and the
 * per-face geometry every later stage uses. */
#include "common/mesh.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"

rs_mesh *rs_mesh_new(size_t nverts, size_t nfaces)
{
    if (nverts > SIZE_MAX / (3 * sizeof(float)) || nfaces > SIZE_MAX / (3 * sizeof(uint32_t))) return NULL;
    rs_mesh *m = calloc(1, sizeof *m);
    if (!m) return NULL;
    m->verts = calloc(nverts ? 3 * nverts : 1, sizeof *m->verts);
    m->tris = calloc(nfaces ? 3 * nfaces : 1, sizeof *m->tris);
    if (!m->verts || !m->tris) {
        rs_mesh_free(m);
        return NULL;
    }
    m->nverts = nverts;
    m->nfaces = nfaces;
    return m;
}

void rs_mesh_free(rs_mesh *m)
{
    if (!m) return;
    free(m->verts);
    free(m->tris);
    free(m);
}

static const rs_ply_prop *scalar_prop(const rs_ply_element *el, const char *name)
{
    const rs_ply_prop *p = rs_ply_find_prop(el, name);
    return p && !p->is_list ? p : NULL;
}

rs_mesh *rs_mesh_from_ply(const rs_ply *ply, const char *name, rs_err *err)
{
    const rs_ply_element *ve = rs_ply_find_element(ply, "vertex");
    const rs_ply_element *fe = rs_ply_find_element(ply, "face");
    const rs_ply_prop *px = ve ? scalar_prop(ve, "x") : NULL, *py = ve ? scalar_prop(ve, "y") : NULL,
                      *pz = ve ? scalar_prop(ve, "z") : NULL;
    if (!px || !py || !pz) {
        rs_err_set(err, RS_ERR_INPUT, name, 0, "no vertex element with scalar x, y and z; expected a mesh");
        return NULL;
    }
    const rs_ply_prop *pi = fe ? rs_ply_find_prop(fe, "vertex_indices") : NULL;
    if (fe && !pi) pi = rs_ply_find_prop(fe, "vertex_index");
    if (!pi || !pi->is_list) {
        rs_err_set(err, RS_ERR_INPUT, name, 0,
                   "no face element with a vertex_indices (or vertex_index) list; expected a polygon mesh");
        return NULL;
    }
    if (ve->count > UINT32_MAX) {
        rs_err_set(err, RS_ERR_INPUT, name, 0, "%zu vertices; at most %u are supported", ve->count, UINT32_MAX);
        return NULL;
    }
    /* Polygons of n vertices become n - 2 triangles (fans). */
    size_t ntris = 0;
    for (size_t f = 0; f < fe->count; f++) {
        size_t n = pi->offsets[f + 1] - pi->offsets[f];
        if (n < 3) {
            rs_err_set(err, RS_ERR_INPUT, name, 0, "face %zu has %zu vertices; expected 3 or more", f, n);
            return NULL;
        }
        ntris += n - 2;
    }
    rs_mesh *m = rs_mesh_new(ve->count, ntris);
    if (!m) {
        rs_err_set(err, RS_ERR_SYSTEM, name, 0, "out of memory for %zu vertices and %zu triangles", ve->count, ntris);
        return NULL;
    }
    for (size_t v = 0; v < ve->count; v++) {
        double c[3] = {px->data[v], py->data[v], pz->data[v]};
        for (int j = 0; j < 3; j++) {
            /* Finite as a double is not enough: 1e300 overflows the float. */
            if (!isfinite(c[j]) || fabs(c[j]) > FLT_MAX) {
                rs_err_set(err, RS_ERR_INPUT, name, 0,
                           "vertex %zu: coordinates (%g, %g, %g); expected finite "
                           "numbers within the float range",
                           v, c[0], c[1], c[2]);
                rs_mesh_free(m);
                return NULL;
            }
            m->verts[3 * v + j] = (float)c[j];
        }
    }
    size_t t = 0;
    for (size_t f = 0; f < fe->count; f++) {
        const double *idx = pi->data + pi->offsets[f];
        size_t n = pi->offsets[f + 1] - pi->offsets[f];
        for (size_t j = 0; j < n; j++)
            if (!(idx[j] >= 0 && idx[j] < (double)ve->count && idx[j] == floor(idx[j]))) {
                rs_err_set(err, RS_ERR_INPUT, name, 0, "face %zu: vertex index %g; expected an integer from 0 to %zu",
                           f, idx[j], ve->count - 1 + (ve->count == 0));
                rs_mesh_free(m);
                return NULL;
            }
        for (size_t j = 1; j + 1 < n; j++, t++) {
            m->tris[3 * t] = (uint32_t)idx[0];
            m->tris[3 * t + 1] = (uint32_t)idx[j];
            m->tris[3 * t + 2] = (uint32_t)idx[j + 1];
        }
    }
    return m;
}

rs_ply_element *rs_mesh_to_ply(const rs_mesh *m, rs_ply *ply)
{
    size_t n = m->nverts > m->nfaces ? m->nverts : m->nfaces;
    float *col = malloc((n ? n : 1) * 3 * sizeof *col);
    double *idx = malloc((m->nfaces ? m->nfaces : 1) * 3 * sizeof *idx);
    rs_ply_element *fe = NULL;
    if (!col || !idx) goto out;
    /* PLY stores one array per property: split x, y and z apart. */
    for (size_t v = 0; v < m->nverts; v++)
        for (int j = 0; j < 3; j++) col[j * m->nverts + v] = m->verts[3 * v + j];
    rs_ply_element *ve = rs_ply_add_element(ply, "vertex", m->nverts);
    if (!ve || !rs_ply_add_scalar_f(ve, "x", RS_PLY_FLOAT32, col) ||
        !rs_ply_add_scalar_f(ve, "y", RS_PLY_FLOAT32, col + m->nverts) ||
        !rs_ply_add_scalar_f(ve, "z", RS_PLY_FLOAT32, col + 2 * m->nverts))
        goto out;
    for (size_t i = 0; i < 3 * m->nfaces; i++) idx[i] = m->tris[i];
    rs_ply_element *el = rs_ply_add_element(ply, "face", m->nfaces);
    if (!el || !rs_ply_add_list_fixed(el, "vertex_indices", RS_PLY_UINT8, RS_PLY_INT32, 3, idx)) goto out;
    fe = el;
out:
    free(col);
    free(idx);
    return fe;
}

rs_mesh *rs_mesh_read(const char *path, rs_ply **ply_out, rs_err *err)
{
    if (ply_out) *ply_out = NULL;
    rs_ply *ply = rs_ply_read(path, err);
    if (!ply) return NULL;
    rs_mesh *m = rs_mesh_from_ply(ply, path, err);
    if (m && ply_out)
        *ply_out = ply;
    else
        rs_ply_free(ply);
    return m;
}

void rs_mesh_face(const rs_mesh *m, size_t f, rs_v3 *centroid, rs_v3 *normal, double *area)
{
    const uint32_t *t = m->tris + 3 * f;
    rs_v3 a = rs_mesh_vert(m, t[0]), b = rs_mesh_vert(m, t[1]), c = rs_mesh_vert(m, t[2]);
    rs_v3 n = rs_v3_cross(rs_v3_sub(b, a), rs_v3_sub(c, a));
    double len = rs_v3_len(n);
    if (centroid) *centroid = rs_v3_scale(rs_v3_add(rs_v3_add(a, b), c), 1.0 / 3.0);
    if (normal) *normal = len > 0 ? rs_v3_scale(n, 1.0 / len) : rs_v3_make(0, 0, 0);
    if (area) *area = 0.5 * len;
}

double rs_mesh_extent(const rs_mesh *m)
{
    if (m->nverts == 0) return 0;
    double lo[3], hi[3];
    for (int j = 0; j < 3; j++) lo[j] = hi[j] = m->verts[j];
    for (size_t v = 1; v < m->nverts; v++)
        for (int j = 0; j < 3; j++) {
            double x = m->verts[3 * v + j];
            lo[j] = x < lo[j] ? x : lo[j];
            hi[j] = x > hi[j] ? x : hi[j];
        }
    return sqrt((hi[0] - lo[0]) * (hi[0] - lo[0]) + (hi[1] - lo[1]) * (hi[1] - lo[1]) +
                (hi[2] - lo[2]) * (hi[2] - lo[2]));
}

double *rs_mesh_edge_lengths(const rs_mesh *m, size_t *n)
{
    *n = 0;
    size_t nv = m->nverts;
    size_t *start = calloc(nv + 1, sizeof *start);
    uint32_t *faces = malloc((m->nfaces ? 3 * m->nfaces : 1) * sizeof *faces);
    size_t *mark = calloc(nv ? nv : 1, sizeof *mark);
    double *len = malloc((m->nfaces ? 3 * m->nfaces : 1) * sizeof *len);
    if (!start || !faces || !mark || !len) goto fail;
    /* Vertex -> faces (CSR), then each vertex's higher-numbered neighbours once. */
    for (size_t k = 0; k < 3 * m->nfaces; k++)
        if (m->tris[k] < nv) start[m->tris[k] + 1]++;
    for (size_t v = 0; v < nv; v++) start[v + 1] += start[v];
    for (size_t f = 0; f < m->nfaces; f++)
        for (int j = 0; j < 3; j++) {
            uint32_t v = m->tris[3 * f + j];
            if (v < nv) faces[start[v]++] = (uint32_t)f;
        }
    for (size_t v = nv; v > 0; v--) start[v] = start[v - 1];
    start[0] = 0;
    for (size_t a = 0; a < nv; a++) {
        rs_v3 pa = rs_mesh_vert(m, (uint32_t)a);
        for (size_t k = start[a]; k < start[a + 1]; k++)
            for (int j = 0; j < 3; j++) {
                uint32_t b = m->tris[3 * (size_t)faces[k] + j];
                if (b <= a || b >= nv || mark[b] == a + 1) continue;
                mark[b] = a + 1;
                len[(*n)++] = rs_v3_len(rs_v3_sub(rs_mesh_vert(m, b), pa));
            }
    }
    free(start);
    free(faces);
    free(mark);
    if (*n == 0) {
        free(len);
        return NULL;
    }
    return len;
fail:
    free(start);
    free(faces);
    free(mark);
    free(len);
    return NULL;
}

/* Half an ulp of a float at x, bounded above: what rounding a decimal value to x can move it. */
static double rounding(double x)
{
    return fabs(x) * 0x1p-24 + 0x1p-149;
}

int rs_mesh_face_collinear(const rs_mesh *m, size_t f)
{
    const uint32_t *t = m->tris + 3 * f;
    const float *a = m->verts + 3 * (size_t)t[0], *b = m->verts + 3 * (size_t)t[1], *c = m->verts + 3 * (size_t)t[2];
    double u[3], v[3], du[3], dv[3];
    for (int j = 0; j < 3; j++) {
        u[j] = (double)b[j] - a[j];
        v[j] = (double)c[j] - a[j];
        du[j] = rounding(a[j]) + rounding(b[j]);
        dv[j] = rounding(a[j]) + rounding(c[j]);
    }
    /* Each component of u x v against the first-order change the corners' rounding can make in
     * it; within twice that everywhere, the corners may have been on one line before rounding. */
    for (int i = 0; i < 3; i++) {
        int j = (i + 1) % 3, k = (i + 2) % 3;
        double n = u[j] * v[k] - u[k] * v[j];
        double dn = du[j] * fabs(v[k]) + fabs(u[j]) * dv[k] + du[k] * fabs(v[j]) + fabs(u[k]) * dv[j];
        if (fabs(n) > 2 * dn) return 0;
    }
    return 1;
}

/* Face f's corners from its lowest one (x, then y, then z), winding kept: the key of its place. */
static void face_key(const rs_mesh *m, size_t f, float key[9])
{
    const uint32_t *t = m->tris + 3 * f;
    int r = 0;
    for (int k = 1; k < 3; k++) {
        const float *p = m->verts + 3 * (size_t)t[k], *q = m->verts + 3 * (size_t)t[r];
        if (p[0] < q[0] || (p[0] == q[0] && (p[1] < q[1] || (p[1] == q[1] && p[2] < q[2])))) r = k;
    }
    for (int k = 0; k < 3; k++)
        for (int j = 0; j < 3; j++) key[3 * k + j] = m->verts[3 * (size_t)t[(r + k) % 3] + j] + 0.0f; /* -0 -> +0 */
}

static uint64_t key_hash(const float key[9])
{
    uint64_t h = 0xcbf29ce484222325ULL;
    for (int k = 0; k < 9; k++) {
        uint32_t bits;
        memcpy(&bits, &key[k], sizeof bits);
        h = (h ^ bits) * 0x100000001b3ULL;
        h ^= h >> 29;
    }
    return h;
}

static long mark_coincident(const rs_mesh *m, uint8_t *drop, rs_progress *progress)
{
    size_t cap = 16;
    while (cap < 2 * m->nfaces) cap *= 2;
    uint32_t *slot = malloc(cap * sizeof *slot);
    if (!slot) return -1;
    for (size_t k = 0; k < cap; k++) slot[k] = UINT32_MAX;
    long marked = 0;
    for (size_t f = 0; f < m->nfaces; f++) {
        if (drop[f]) continue;
        float key[9], other[9];
        face_key(m, f, key);
        /* Open addressing, first come first kept: the same input gives the same faces. */
        for (size_t k = key_hash(key) & (cap - 1);; k = (k + 1) & (cap - 1)) {
            if (slot[k] == UINT32_MAX) {
                slot[k] = (uint32_t)f;
                break;
            }
            face_key(m, slot[k], other);
            if (memcmp(key, other, sizeof key) == 0) {
                drop[f] = 1;
                marked++;
                break;
            }
        }
        if (progress && (f + 1) % 65536 == 0) rs_progress_add(progress, 65536);
    }
    if (progress) rs_progress_add(progress, m->nfaces % 65536);
    free(slot);
    return marked;
}

int rs_mesh_mark_degenerate(const rs_mesh *m, double min_area, uint8_t *drop, rs_mesh_degenerate *count,
                            rs_progress *progress)
{
    memset(count, 0, sizeof *count);
    if (m->nfaces >= UINT32_MAX) return -1;
    for (size_t f = 0; f < m->nfaces; f++) {
        double area;
        rs_mesh_face(m, f, NULL, NULL, &area);
        const uint32_t *t = m->tris + 3 * f;
        if (!(area > min_area) || t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
            drop[f] = 1;
            count->zero_area++;
        } else if (rs_mesh_face_collinear(m, f)) {
            drop[f] = 1;
            count->collinear++;
        }
        if (progress && (f + 1) % 65536 == 0) rs_progress_add(progress, 65536);
    }
    if (progress) rs_progress_add(progress, m->nfaces % 65536);
    long dup = mark_coincident(m, drop, progress);
    if (dup < 0) return -1;
    count->coincident = (size_t)dup;
    return 0;
}

/* overlap: drops the faces of each scan's sheet where another scan saw the same surface
 * better (see overlap.h), with one Embree scene per scan. */
#include "meshing/overlap.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "common/scene.h"

#define BLOCK        1024
#define MAX_ATTEMPTS 3
/* Faces a dedup line may cross within the tolerance before it gives up. */
#define MAX_CROSSINGS 8
/* Two sheets are one surface only when they face the same way: cos 45 degrees. */
#define COS_SAME_FACING 0.7071

typedef struct scan_part {
    rs_mesh *mesh;  /* all vertices, this scan's faces */
    size_t *global; /* its face k is face global[k] of the input */
    rs_scene *scene;
} scan_part;

static void parts_free(scan_part *p, int n)
{
    if (!p) return;
    for (int s = 0; s < n; s++) {
        rs_scene_free(p[s].scene);
        rs_mesh_free(p[s].mesh);
        free(p[s].global);
    }
    free(p);
}

/* Footprint of a sample of face normal n at point c seen from o: range / |cos incidence|. */
static double footprint(rs_v3 c, rs_v3 n, const double o[3])
{
    rs_v3 d = rs_v3_sub(rs_v3_make(o[0], o[1], o[2]), c);
    double r = rs_v3_len(d), cs = fabs(rs_v3_dot(n, d)) / (r > 0 ? r : 1);
    return cs > 1e-6 ? r / cs : INFINITY;
}

/* Face normals averaged over the faces around their corners (area-weighted): where grid cells
 * are as small as the range noise a single face's normal is mostly noise. NULL when out of
 * memory. */
static float *smooth_normals(const rs_mesh *m)
{
    float *vn = calloc(m->nverts ? 3 * m->nverts : 1, sizeof *vn);
    float *fn = malloc((m->nfaces ? m->nfaces : 1) * 3 * sizeof *fn);
    if (!vn || !fn) {
        free(vn);
        free(fn);
        return NULL;
    }
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 a = rs_mesh_vert(m, m->tris[3 * f]), b = rs_mesh_vert(m, m->tris[3 * f + 1]),
              c = rs_mesh_vert(m, m->tris[3 * f + 2]);
        rs_v3 n = rs_v3_cross(rs_v3_sub(b, a), rs_v3_sub(c, a)); /* length: twice the area */
        for (int j = 0; j < 3; j++) {
            float *v = vn + 3 * (size_t)m->tris[3 * f + j];
            v[0] += (float)n.x;
            v[1] += (float)n.y;
            v[2] += (float)n.z;
        }
    }
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 n = rs_v3_make(0, 0, 0);
        for (int j = 0; j < 3; j++) n = rs_v3_add(n, rs_v3_from_f(vn + 3 * (size_t)m->tris[3 * f + j]));
        double len = rs_v3_len(n);
        for (int j = 0; j < 3; j++) fn[3 * f + j] = len > 0 ? (float)((j == 0 ? n.x : j == 1 ? n.y : n.z) / len) : 0.0f;
    }
    free(vn);
    return fn;
}

int rs_overlap_resolve(const rs_mesh *m, const int *owner, const uint8_t *guess, const rs_scan *scans, int nscans,
                       double tol_m, uint8_t *drop, rs_overlap_stats *st, rs_err *err)
{
    memset(st, 0, sizeof *st);
    memset(drop, 0, m->nfaces);
    if (nscans < 2) return 0;
    scan_part *parts = calloc((size_t)nscans, sizeof *parts);
    size_t *count = calloc((size_t)nscans, sizeof *count);
    float *sn = smooth_normals(m);
    int rc = -1;
    if (!parts || !count || !sn) goto nomem;
    /* Guessed faces (nadir caps) are not in the scenes: they never stand for an observation. */
    for (size_t f = 0; f < m->nfaces; f++) count[owner[f]] += !(guess && guess[f]);
    for (int s = 0; s < nscans; s++) {
        parts[s].mesh = rs_mesh_new(m->nverts, count[s]);
        parts[s].global = malloc((count[s] ? count[s] : 1) * sizeof *parts[s].global);
        if (!parts[s].mesh || !parts[s].global) goto nomem;
        memcpy(parts[s].mesh->verts, m->verts, 3 * m->nverts * sizeof(float));
        size_t k = 0;
        for (size_t f = 0; f < m->nfaces; f++)
            if (owner[f] == s && !(guess && guess[f])) {
                memcpy(parts[s].mesh->tris + 3 * k, m->tris + 3 * f, 3 * sizeof(uint32_t));
                parts[s].global[k++] = f;
            }
        if (count[s] && !(parts[s].scene = rs_scene_new(parts[s].mesh, err))) goto out;
    }

    size_t rays = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : rays)
    for (size_t start = 0; start < m->nfaces; start += BLOCK) {
        size_t end = start + BLOCK < m->nfaces ? start + BLOCK : m->nfaces;
        rs_ray ray[BLOCK];
        rs_hit hit[BLOCK];
        rs_v3 cen[BLOCK], nrm[BLOCK];
        for (size_t f = start; f < end; f++) {
            rs_mesh_face(m, f, &cen[f - start], NULL, NULL);
            nrm[f - start] = rs_v3_from_f(sn + 3 * f);
        }
        for (int t = 0; t < nscans; t++) {
            if (!parts[t].scene) continue;
            const double *o = scans[t].position;
            for (size_t f = start; f < end; f++) {
                rs_ray *r = &ray[f - start];
                r->org = rs_v3_make(o[0], o[1], o[2]);
                r->dir = rs_v3_sub(cen[f - start], r->org);
                double len = rs_v3_len(r->dir);
                /* Only faces of t near the centroid count (t in units of the ray's length). */
                r->tnear = len > tol_m ? 1 - tol_m / len : 0;
                r->tfar = 1 + tol_m / (len > 0 ? len : 1);
                if (owner[f] == t || drop[f]) r->tnear = r->tfar = NAN; /* skipped: not finite */
            }
            /* The first face in the window may be another surface (the wall beside a floor,
             * at a corner): look past it, a few times. */
            for (int attempt = 0; attempt < MAX_ATTEMPTS; attempt++) {
                rs_scene_intersect(parts[t].scene, ray, hit, end - start);
                for (size_t f = start; f < end; f++) {
                    rs_ray *r = &ray[f - start];
                    if (!isfinite(r->tnear)) continue;
                    rays++;
                    const rs_hit *h = &hit[f - start];
                    r->tnear = r->tfar = NAN; /* done with f unless it looks further below */
                    if (h->face == RS_NO_HIT) continue;
                    rs_v3 n_t = rs_v3_from_f(sn + 3 * parts[t].global[h->face]), c = cen[f - start];
                    rs_v3 n = nrm[f - start];
                    /* One surface: t's face and f face the same way, and t sees f's front. */
                    if (rs_v3_dot(n, n_t) < COS_SAME_FACING || rs_v3_dot(n, rs_v3_sub(r->org, c)) <= 0) {
                        double len = rs_v3_len(r->dir);
                        r->tnear = h->t + 1e-6 / (len > 0 ? len : 1);
                        r->tfar = 1 + tol_m / (len > 0 ? len : 1);
                        continue;
                    }
                    if (guess && guess[f]) {
                        drop[f] = 1;
                        continue;
                    }
                    rs_v3 p_t = rs_v3_add(r->org, rs_v3_scale(r->dir, h->t));
                    /* One normal for both sides, the mean of the two faces'. */
                    rs_v3 n_mean = rs_v3_norm(rs_v3_add(n, n_t));
                    double q_s = footprint(c, n_mean, scans[owner[f]].position), q_t = footprint(p_t, n_mean, o);
                    if (q_t < q_s || (q_t == q_s && t < owner[f])) drop[f] = 1;
                }
            }
        }
    }
    st->rays = rays;
    for (size_t f = 0; f < m->nfaces; f++) {
        st->dropped += drop[f];
        st->dropped_guess += drop[f] && guess && guess[f];
    }
    rc = 0;
    goto out;
nomem:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory resolving the overlaps of %d scans", nscans);
out:
    parts_free(parts, nscans);
    free(count);
    free(sn);
    return rc;
}

static uint32_t root(uint32_t *parent, uint32_t v)
{
    while (parent[v] != v) v = parent[v] = parent[parent[v]];
    return v;
}

int rs_overlap_dedup(rs_mesh *m, double tol_m, size_t *removed, rs_err *err)
{
    *removed = 0;
    uint32_t *parent = malloc((m->nverts ? m->nverts : 1) * sizeof *parent);
    uint8_t *drop = calloc(m->nfaces ? m->nfaces : 1, 1);
    rs_scene *sc = NULL;
    int rc = -1;
    if (!parent || !drop) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    for (size_t v = 0; v < m->nverts; v++) parent[v] = (uint32_t)v;
    for (size_t f = 0; f < m->nfaces; f++)
        for (int j = 1; j < 3; j++) {
            uint32_t a = root(parent, m->tris[3 * f]), b = root(parent, m->tris[3 * f + j]);
            if (a != b) parent[a < b ? b : a] = a < b ? a : b; /* smaller index as root: order-free */
        }
    for (size_t v = 0; v < m->nverts; v++) parent[v] = root(parent, (uint32_t)v);
    if (!(sc = rs_scene_new(m, err))) goto out;
#pragma omp parallel for schedule(dynamic, 1024)
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 c, n;
        double area;
        rs_mesh_face(m, f, &c, &n, &area);
        if (!(area > 0)) continue;
        /* One ray along the normal line through the centroid, from tol_m behind to tol_m in
         * front, taking every face it crosses in turn: sheets a fraction of a millimetre apart
         * (two scans of the same ground) lie inside any offset a ray from the face would need
         * to leave it, and the first face crossed may be of f's own sheet. */
        rs_ray r;
        r.org = rs_v3_sub(c, rs_v3_scale(n, tol_m));
        r.dir = n;
        r.tnear = 0;
        r.tfar = 2 * tol_m;
        for (int k = 0; k < MAX_CROSSINGS; k++) {
            rs_hit h;
            rs_scene_intersect(sc, &r, &h, 1);
            uint32_t g = h.face;
            if (g == RS_NO_HIT) break;
            r.tnear = h.t + 1e-6; /* 1 um past the face crossed: beyond float rounding of t */
            if (g == f || parent[m->tris[3 * (size_t)g]] == parent[m->tris[3 * f]]) continue;
            if (rs_v3_dot(rs_scene_normal(sc, g), n) < COS_SAME_FACING) continue;
            double area_g;
            rs_mesh_face(m, g, NULL, NULL, &area_g);
            /* Either face's line may find the pair (a centroid's line can miss the other,
             * larger face): mark the smaller one, whichever found it; the union does not
             * depend on order. */
            size_t loser = area < area_g || (area == area_g && f > g) ? f : g;
#pragma omp atomic write
            drop[loser] = 1;
        }
    }
    size_t kept = 0;
    for (size_t f = 0; f < m->nfaces; f++)
        if (!drop[f]) memmove(m->tris + 3 * kept++, m->tris + 3 * f, 3 * sizeof *m->tris);
    *removed = m->nfaces - kept;
    m->nfaces = kept;
    rc = 0;
out:
    rs_scene_free(sc);
    free(parent);
    free(drop);
    return rc;
}

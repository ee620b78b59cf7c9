/* scene: Embree 3 wrapper (see scene.h). */
#include "common/scene.h"

#include <embree3/rtcore.h>
#include <float.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef _OPENMP
#include <omp.h>
#endif

struct rs_scene {
    RTCDevice device;
    RTCScene scene;
    const rs_mesh *mesh;
    float *normals; /* 3 per face */
    double extent;
    rs_err build_err;
    int failed;
    RTCScene occ;          /* the occluders (NULL without) */
    const uint32_t *proxy; /* per occluder face: the facet that stands for it */
    size_t occ_faces;
    float *occ_normals; /* 3 per occluder face: toward the known side */
    float occ_near;     /* occluder hits nearer than this to the ray's origin do not count, m */
};

static void embree_error(void *user, enum RTCError code, const char *str)
{
    rs_scene *s = user;
    if (s->failed) return;
    s->failed = 1;
    rs_err_set(&s->build_err, RS_ERR_INTERNAL, NULL, 0, "Embree error %d: %s", (int)code, str ? str : "");
}

/* The unit normal of every face of m, 3 floats each (zero for degenerate faces); NULL when out of
 * memory. */
static float *face_normals(const rs_mesh *m)
{
    float *nrm = malloc((m->nfaces ? m->nfaces : 1) * 3 * sizeof *nrm);
    if (!nrm) return NULL;
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(m, f, &c, &n, &a);
        nrm[3 * f] = (float)n.x;
        nrm[3 * f + 1] = (float)n.y;
        nrm[3 * f + 2] = (float)n.z;
    }
    return nrm;
}

/* A committed Embree scene of mesh's triangles on s's device (NULL when Embree failed).
 * Embree reads copies in buffers it owns (it needs 16 bytes of padding past the last vertex for
 * SSE loads). */
static RTCScene build_bvh(rs_scene *s, const rs_mesh *mesh)
{
    RTCScene scene = rtcNewScene(s->device);
    if (!scene) return NULL;
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geom = rtcNewGeometry(s->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    float *vb =
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh->nverts);
    unsigned *ib =
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), mesh->nfaces);
    if (!vb || !ib) {
        rtcReleaseGeometry(geom);
        rtcReleaseScene(scene);
        return NULL;
    }
    memcpy(vb, mesh->verts, mesh->nverts * 3 * sizeof(float));
    memcpy(ib, mesh->tris, mesh->nfaces * 3 * sizeof(unsigned));
    rtcCommitGeometry(geom);
    rtcAttachGeometry(scene, geom);
    rtcReleaseGeometry(geom); /* the scene holds its own reference */
    rtcCommitScene(scene);
    return scene;
}

rs_scene *rs_scene_new(const rs_mesh *mesh, rs_err *err)
{
    if (mesh->nfaces == 0 || mesh->nverts == 0)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "the mesh has no faces"), NULL;
    if (mesh->nfaces > 0x7fffffffU)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "too many faces (%zu)", mesh->nfaces), NULL;
    rs_scene *s = calloc(1, sizeof *s);
    if (!s) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory"), NULL;
    s->mesh = mesh;
    if (!(s->normals = face_normals(mesh))) goto oom;
    s->extent = rs_mesh_extent(mesh);

    /* Embree's TBB threads would fight OpenMP's: give it as many as OpenMP uses. */
    char cfg[64];
    int threads = 1;
#ifdef _OPENMP
    threads = omp_get_max_threads();
#endif
    snprintf(cfg, sizeof cfg, "threads=%d", threads);
    s->device = rtcNewDevice(cfg);
    if (!s->device) {
        rs_err_set(err, RS_ERR_INTERNAL, NULL, 0, "Embree device creation failed (error %d)",
                   (int)rtcGetDeviceError(NULL));
        rs_scene_free(s);
        return NULL;
    }
    rtcSetDeviceErrorFunction(s->device, embree_error, s);
    if (!(s->scene = build_bvh(s, mesh))) goto embree_fail;
    if (s->failed) goto embree_fail;
    return s;
embree_fail:
    if (err) *err = s->build_err;
    if (!s->failed) rs_err_set(err, RS_ERR_INTERNAL, NULL, 0, "Embree could not build the scene");
    rs_scene_free(s);
    return NULL;
oom:
    rs_scene_free(s);
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory building the scene");
    return NULL;
}

void rs_scene_free(rs_scene *s)
{
    if (!s) return;
    if (s->scene) rtcReleaseScene(s->scene);
    if (s->occ) rtcReleaseScene(s->occ);
    if (s->device) rtcReleaseDevice(s->device);
    free(s->normals);
    free(s->occ_normals);
    free(s);
}

const rs_mesh *rs_scene_mesh(const rs_scene *s)
{
    return s->mesh;
}

rs_v3 rs_scene_normal(const rs_scene *s, uint32_t f)
{
    return rs_v3_from_f(s->normals + 3 * (size_t)f);
}

int rs_scene_set_occluders(rs_scene *s, const rs_mesh *occ, const uint32_t *proxy, double near, rs_err *err)
{
    if (s->occ) rtcReleaseScene(s->occ);
    s->occ = NULL;
    s->proxy = NULL;
    s->occ_faces = 0;
    free(s->occ_normals);
    s->occ_normals = NULL;
    if (!occ || occ->nfaces == 0) return 0;
    if (occ->nfaces > 0x7fffffffU)
        return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "too many occluder faces (%zu)", occ->nfaces);
    for (size_t f = 0; f < occ->nfaces; f++)
        if (proxy[f] >= s->mesh->nfaces)
            return rs_err_set(err, RS_ERR_INPUT, NULL, 0, "occluder face %zu: proxy facet %u, expected below %zu", f,
                              (unsigned)proxy[f], s->mesh->nfaces);
    if (!(s->occ_normals = face_normals(occ)))
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu occluder faces", occ->nfaces);
    s->failed = 0;
    if (!(s->occ = build_bvh(s, occ)) || s->failed) {
        if (err) *err = s->build_err;
        if (!s->failed) rs_err_set(err, RS_ERR_INTERNAL, NULL, 0, "Embree could not build the occluders");
        if (s->occ) rtcReleaseScene(s->occ);
        s->occ = NULL;
        s->failed = 0;
        return -1;
    }
    s->proxy = proxy;
    s->occ_faces = occ->nfaces;
    s->occ_near = (float)near;
    return 0;
}

size_t rs_scene_occluder_faces(const rs_scene *s)
{
    return s->occ_faces;
}

double rs_scene_offset(const rs_scene *s, rs_v3 p)
{
    double mag = fmax(fabs(p.x), fmax(fabs(p.y), fabs(p.z)));
    return 1e-5 * s->extent + 64.0 * FLT_EPSILON * mag;
}

static int ray_ok(const rs_ray *r)
{
    return rs_v3_finite(r->org) && rs_v3_finite(r->dir) && isfinite(r->tnear) && r->tnear >= 0 && !isnan(r->tfar) &&
        r->tfar > r->tnear && rs_v3_dot(r->dir, r->dir) > 0;
}

static void fill_ray(struct RTCRay *er, const rs_ray *r)
{
    er->org_x = (float)r->org.x;
    er->org_y = (float)r->org.y;
    er->org_z = (float)r->org.z;
    er->dir_x = (float)r->dir.x;
    er->dir_y = (float)r->dir.y;
    er->dir_z = (float)r->dir.z;
    er->tnear = (float)r->tnear;
    er->tfar = r->tfar > FLT_MAX ? INFINITY : (float)r->tfar;
    er->time = 0;
    er->mask = 0xFFFFFFFFU; /* Debian's Embree has ray masks on: mask 0 hits nothing */
    er->id = 0;
    er->flags = 0;
}

enum { BATCH = 256 };

/* Ray r (escaped from the mesh) against the occluders, which face the known side: blocked at the
 * first face it crosses into unknown space beyond occ_near of its origin, or at occ_near when it
 * is inside unknown space there (it crossed into it nearer, and not out again). Returns 1 and
 * *t, *face (the occluder face) when blocked. */
static int trace_occluders(const rs_scene *s, const rs_ray *r, float *t, uint32_t *face)
{
    double len = sqrt(rs_v3_dot(r->dir, r->dir));
    float near = (float)fmax(r->tnear, s->occ_near / len), tfar = r->tfar > FLT_MAX ? INFINITY : (float)r->tfar;
    float tn = (float)r->tnear;
    int inside = 0;
    uint32_t last = 0;
    struct RTCIntersectContext ctx;
    for (int round = 0; round < 16; round++) {
        struct RTCRayHit rh;
        fill_ray(&rh.ray, r);
        rh.ray.tnear = tn;
        rh.ray.tfar = tfar;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
        rtcInitIntersectContext(&ctx);
        rtcIntersect1(s->occ, &ctx, &rh);
        if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) break;
        float th = rh.ray.tfar;
        const float *n = s->occ_normals + 3 * (size_t)rh.hit.primID;
        int entering = r->dir.x * n[0] + r->dir.y * n[1] + r->dir.z * n[2] < 0;
        if (th >= near) {
            if (!entering && !inside) break; /* leaving unknown space it never entered: a seam */
            *t = inside ? near : th;
            *face = inside ? last : rh.hit.primID;
            return 1;
        }
        inside = entering;
        last = rh.hit.primID;
        tn = nextafterf(th, INFINITY);
    }
    if (!inside || !(near < tfar)) return 0;
    *t = near;
    *face = last;
    return 1;
}

/* The rays of rh (their rays map[]) that escaped the mesh, traced against the occluders. */
static void intersect_occluders(const rs_scene *s, const rs_ray *rays, rs_hit *hits, const struct RTCRayHit *rh,
                                const size_t *map, size_t m)
{
    for (size_t q = 0; q < m; q++) {
        if (rh[q].hit.geomID != RTC_INVALID_GEOMETRY_ID) continue;
        float t;
        uint32_t face;
        if (!trace_occluders(s, &rays[map[q]], &t, &face)) continue;
        rs_hit *h = &hits[map[q]];
        h->face = s->proxy[face];
        h->t = t;
        h->u = h->v = 0;
        h->backface = 1;
        h->occluder = 1;
    }
}

static void intersect(const rs_scene *s, const rs_ray *rays, rs_hit *hits, size_t n,
                      enum RTCIntersectContextFlags flags)
{
    struct RTCRayHit rh[BATCH];
    size_t map[BATCH];
    struct RTCIntersectContext ctx;
    for (size_t start = 0; start < n; start += BATCH) {
        size_t end = start + BATCH < n ? start + BATCH : n, m = 0;
        for (size_t k = start; k < end; k++) {
            hits[k].face = RS_NO_HIT;
            hits[k].t = INFINITY;
            hits[k].u = hits[k].v = 0;
            hits[k].backface = 0;
            hits[k].occluder = 0;
            if (!ray_ok(&rays[k])) continue;
            fill_ray(&rh[m].ray, &rays[k]);
            rh[m].hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rh[m].hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
            map[m++] = k;
        }
        if (!m) continue;
        rtcInitIntersectContext(&ctx);
        ctx.flags = flags;
        rtcIntersect1M(s->scene, &ctx, rh, (unsigned)m, sizeof(struct RTCRayHit));
        for (size_t q = 0; q < m; q++) {
            if (rh[q].hit.geomID == RTC_INVALID_GEOMETRY_ID) continue;
            rs_hit *h = &hits[map[q]];
            h->face = rh[q].hit.primID;
            h->t = rh[q].ray.tfar;
            h->u = rh[q].hit.u;
            h->v = rh[q].hit.v;
            h->backface = rs_v3_dot(rays[map[q]].dir, rs_scene_normal(s, h->face)) > 0;
        }
        if (s->occ) intersect_occluders(s, rays, hits, rh, map, m);
    }
}

void rs_scene_intersect(const rs_scene *s, const rs_ray *rays, rs_hit *hits, size_t n)
{
    intersect(s, rays, hits, n, RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT);
}

void rs_scene_intersect_coherent(const rs_scene *s, const rs_ray *rays, rs_hit *hits, size_t n)
{
    intersect(s, rays, hits, n, RTC_INTERSECT_CONTEXT_FLAG_COHERENT);
}

void rs_scene_occluded(const rs_scene *s, const rs_ray *rays, uint8_t *occluded, size_t n)
{
    struct RTCRay r[BATCH];
    size_t map[BATCH];
    struct RTCIntersectContext ctx;
    for (size_t start = 0; start < n; start += BATCH) {
        size_t end = start + BATCH < n ? start + BATCH : n, m = 0;
        for (size_t k = start; k < end; k++) {
            occluded[k] = 0;
            if (!ray_ok(&rays[k])) continue;
            fill_ray(&r[m], &rays[k]);
            map[m++] = k;
        }
        if (!m) continue;
        rtcInitIntersectContext(&ctx);
        ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_INCOHERENT;
        rtcOccluded1M(s->scene, &ctx, r, (unsigned)m, sizeof(struct RTCRay));
        for (size_t q = 0; q < m; q++) occluded[map[q]] = r[q].tfar < 0; /* -inf when occluded */
        if (!s->occ) continue;
        for (size_t q = 0; q < m; q++) {
            float t;
            uint32_t face;
            if (!occluded[map[q]] && trace_occluders(s, &rays[map[q]], &t, &face)) occluded[map[q]] = 1;
        }
    }
}

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
};

static void embree_error(void *user, enum RTCError code, const char *str)
{
    rs_scene *s = user;
    if (s->failed) return;
    s->failed = 1;
    rs_err_set(&s->build_err, RS_ERR_INTERNAL, NULL, 0, "Embree error %d: %s", (int)code, str ? str : "");
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
    s->normals = malloc(mesh->nfaces * 3 * sizeof *s->normals);
    if (!s->normals) goto oom;
    for (size_t f = 0; f < mesh->nfaces; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(mesh, f, &c, &n, &a);
        s->normals[3 * f] = (float)n.x;
        s->normals[3 * f + 1] = (float)n.y;
        s->normals[3 * f + 2] = (float)n.z;
    }
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
    s->scene = rtcNewScene(s->device);
    rtcSetSceneBuildQuality(s->scene, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geom = rtcNewGeometry(s->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    /* Shared buffers: Embree reads the mesh's own arrays (needs 16 bytes of padding past the
     * last vertex for SSE loads, hence the copy into a padded buffer it owns). */
    float *vb =
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), mesh->nverts);
    unsigned *ib =
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), mesh->nfaces);
    if (!vb || !ib) {
        rtcReleaseGeometry(geom);
        goto embree_fail;
    }
    memcpy(vb, mesh->verts, mesh->nverts * 3 * sizeof(float));
    memcpy(ib, mesh->tris, mesh->nfaces * 3 * sizeof(unsigned));
    rtcCommitGeometry(geom);
    rtcAttachGeometry(s->scene, geom);
    rtcReleaseGeometry(geom); /* the scene holds its own reference */
    rtcCommitScene(s->scene);
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
    if (s->device) rtcReleaseDevice(s->device);
    free(s->normals);
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
    }
}

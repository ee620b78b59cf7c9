/* meshdist: point-to-mesh distances with Embree's rtcPointQuery and an exact point-triangle
 * distance in the callback (see meshdist.h). */
#include "meshing/meshdist.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

struct rs_meshdist {
    RTCDevice device;
    RTCScene scene;
    rs_mesh *mesh; /* own copy: the callback reads the triangles */
};

typedef struct query_state {
    const rs_mesh *m;
    double p[3];
    double best; /* distance of the nearest point so far */
    size_t face;
} query_state;

static double dot3(const double *a, const double *b)
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

void rs_closest_on_triangle(const double p[3], const double a[3], const double b[3], const double c[3], double out[3])
{
    double ab[3], ac[3], ap[3], bp[3], cp[3];
    for (int j = 0; j < 3; j++) {
        ab[j] = b[j] - a[j];
        ac[j] = c[j] - a[j];
        ap[j] = p[j] - a[j];
        bp[j] = p[j] - b[j];
        cp[j] = p[j] - c[j];
    }
    double d1 = dot3(ab, ap), d2 = dot3(ac, ap);
    if (d1 <= 0 && d2 <= 0) {
        memcpy(out, a, 3 * sizeof *out);
        return;
    }
    double d3 = dot3(ab, bp), d4 = dot3(ac, bp);
    if (d3 >= 0 && d4 <= d3) {
        memcpy(out, b, 3 * sizeof *out);
        return;
    }
    double vc = d1 * d4 - d3 * d2;
    if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        double v = d1 / (d1 - d3);
        for (int j = 0; j < 3; j++) out[j] = a[j] + v * ab[j];
        return;
    }
    double d5 = dot3(ab, cp), d6 = dot3(ac, cp);
    if (d6 >= 0 && d5 <= d6) {
        memcpy(out, c, 3 * sizeof *out);
        return;
    }
    double vb = d5 * d2 - d1 * d6;
    if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        double w = d2 / (d2 - d6);
        for (int j = 0; j < 3; j++) out[j] = a[j] + w * ac[j];
        return;
    }
    double va = d3 * d6 - d5 * d4;
    if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
        double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        for (int j = 0; j < 3; j++) out[j] = b[j] + w * (c[j] - b[j]);
        return;
    }
    double denom = va + vb + vc;
    if (!(denom != 0)) {
        memcpy(out, a, 3 * sizeof *out);
        return;
    } /* degenerate: a corner */
    double v = vb / denom, w = vc / denom;
    for (int j = 0; j < 3; j++) out[j] = a[j] + ab[j] * v + ac[j] * w;
}

/* Embree calls this for every triangle whose box meets the query sphere; shrinking the
 * radius prunes the rest of the BVH. */
static bool query_cb(struct RTCPointQueryFunctionArguments *args)
{
    query_state *q = args->userPtr;
    const uint32_t *t = q->m->tris + 3 * (size_t)args->primID;
    double v[3][3], cp[3];
    for (int k = 0; k < 3; k++)
        for (int j = 0; j < 3; j++) v[k][j] = q->m->verts[3 * (size_t)t[k] + j];
    rs_closest_on_triangle(q->p, v[0], v[1], v[2], cp);
    double d = sqrt((cp[0] - q->p[0]) * (cp[0] - q->p[0]) + (cp[1] - q->p[1]) * (cp[1] - q->p[1]) +
                    (cp[2] - q->p[2]) * (cp[2] - q->p[2]));
    if (d < q->best) {
        q->best = d;
        q->face = args->primID;
        if (d < args->query->radius) {
            args->query->radius = (float)d * (1 + 1e-6f) + 1e-9f; /* float radius: never cut the true nearest */
            return true;
        }
    }
    return false;
}

rs_meshdist *rs_meshdist_new(const rs_mesh *m, rs_err *err)
{
    rs_meshdist *d = calloc(1, sizeof *d);
    if (!d || !(d->mesh = rs_mesh_new(m->nverts, m->nfaces))) {
        free(d);
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the distance query of %zu faces", m->nfaces);
        return NULL;
    }
    memcpy(d->mesh->verts, m->verts, 3 * m->nverts * sizeof(float));
    memcpy(d->mesh->tris, m->tris, 3 * m->nfaces * sizeof(uint32_t));
    d->device = rtcNewDevice("threads=1");
    if (!d->device) goto fail;
    d->scene = rtcNewScene(d->device);
    RTCGeometry g = rtcNewGeometry(d->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                                        m->nverts ? m->nverts : 1);
    unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned),
                                           m->nfaces ? m->nfaces : 1);
    if (!vb || !ib) {
        rtcReleaseGeometry(g);
        goto fail;
    }
    memcpy(vb, m->verts, 3 * m->nverts * sizeof(float));
    memcpy(ib, m->tris, 3 * m->nfaces * sizeof(unsigned));
    rtcCommitGeometry(g);
    rtcAttachGeometry(d->scene, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(d->scene);
    if (rtcGetDeviceError(d->device) != RTC_ERROR_NONE) goto fail;
    return d;
fail:
    rs_err_set(err, RS_ERR_INTERNAL, NULL, 0, "Embree could not build the distance query of %zu faces", m->nfaces);
    rs_meshdist_free(d);
    return NULL;
}

void rs_meshdist_free(rs_meshdist *d)
{
    if (!d) return;
    if (d->scene) rtcReleaseScene(d->scene);
    if (d->device) rtcReleaseDevice(d->device);
    rs_mesh_free(d->mesh);
    free(d);
}

double rs_meshdist_query(const rs_meshdist *d, const double p[3], double max_m, size_t *face)
{
    if (d->mesh->nfaces == 0) return INFINITY;
    query_state q = {d->mesh, {p[0], p[1], p[2]}, INFINITY, 0};
    struct RTCPointQuery pq = {(float)p[0], (float)p[1], (float)p[2], 0.0f, (float)max_m};
    struct RTCPointQueryContext ctx;
    rtcInitPointQueryContext(&ctx);
    rtcPointQuery(d->scene, &pq, &ctx, query_cb, &q);
    if (face) *face = q.face;
    return q.best <= max_m ? q.best : INFINITY;
}

/* cloud: point clouds in memory and their basic operations (see cloud.h). The file formats
 * are modules of their own (cloud_format.c and the readers it lists); this file knows none. */
#include "common/cloud.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void rs_cloud_free(rs_cloud *c)
{
    if (!c) return;
    free(c->xyz);
    free(c->intensity);
    free(c->rgb);
    free(c->normal);
    free(c->valid);
    free(c->scans);
    free(c);
}

size_t rs_cloud_unorganized(const rs_cloud *c)
{
    size_t organized = 0;
    for (int s = 0; s < c->nscans; s++) organized += (size_t)c->scans[s].cols * (size_t)c->scans[s].rows;
    return c->npoints - organized;
}

/* Grows c's arrays to hold total points; new intensity/colour entries are zero. */
int rs_cloud_resize(rs_cloud *c, size_t total, int want_intensity, int want_rgb, rs_err *err)
{
    double *xyz = realloc(c->xyz, (total ? total : 1) * 3 * sizeof *xyz);
    if (xyz) c->xyz = xyz;
    uint8_t *valid = realloc(c->valid, total ? total : 1);
    if (valid) c->valid = valid;
    if (!xyz || !valid) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu points", total);
    if (want_intensity || c->intensity) {
        float *in = realloc(c->intensity, (total ? total : 1) * sizeof *in);
        if (!in) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu points", total);
        if (!c->intensity) memset(in, 0, c->npoints * sizeof *in);
        memset(in + c->npoints, 0, (total - c->npoints) * sizeof *in);
        c->intensity = in;
    }
    if (want_rgb || c->rgb) {
        uint8_t *rgb = realloc(c->rgb, (total ? total : 1) * 3);
        if (!rgb) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu points", total);
        if (!c->rgb) memset(rgb, 0, c->npoints * 3);
        memset(rgb + 3 * c->npoints, 0, 3 * (total - c->npoints));
        c->rgb = rgb;
    }
    if (c->normal) { /* grown only: normals are a file's, never invented for points without */
        float *nrm = realloc(c->normal, (total ? total : 1) * 3 * sizeof *nrm);
        if (!nrm) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu points", total);
        if (total > c->npoints) memset(nrm + 3 * c->npoints, 0, 3 * (total - c->npoints) * sizeof *nrm);
        c->normal = nrm;
    }
    return 0;
}

int rs_cloud_append(rs_cloud *dst, const rs_cloud *src, rs_err *err)
{
    size_t n0 = dst->npoints, total = n0 + src->npoints;
    /* Normals only when every point has one: a cloud without them gets the mesh stage's. */
    if (src->normal && n0 == 0 && !dst->normal) dst->normal = calloc(3, sizeof *dst->normal);
    if (!src->normal || (n0 > 0 && !dst->normal)) {
        free(dst->normal);
        dst->normal = NULL;
    }
    if (rs_cloud_resize(dst, total, src->intensity != NULL, src->rgb != NULL, err) != 0) return -1;
    if (dst->normal) memcpy(dst->normal + 3 * n0, src->normal, 3 * src->npoints * sizeof *src->normal);
    rs_scan *scans = realloc(dst->scans, (size_t)(dst->nscans + src->nscans + 1) * sizeof *scans);
    if (!scans) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    dst->scans = scans;
    /* Into dst's frame: the two origins may differ (world = xyz + origin on both sides). */
    double shift[3];
    for (int j = 0; j < 3; j++) shift[j] = src->origin[j] - dst->origin[j];
    for (size_t i = 0; i < 3 * src->npoints; i++) dst->xyz[3 * n0 + i] = src->xyz[i] + shift[i % 3];
    memcpy(dst->valid + n0, src->valid, src->npoints);
    if (src->intensity) memcpy(dst->intensity + n0, src->intensity, src->npoints * sizeof *src->intensity);
    if (src->rgb) memcpy(dst->rgb + 3 * n0, src->rgb, 3 * src->npoints);
    for (int s = 0; s < src->nscans; s++) {
        dst->scans[dst->nscans] = src->scans[s];
        for (int j = 0; j < 3; j++) dst->scans[dst->nscans].position[j] += shift[j];
        dst->scans[dst->nscans++].first += n0;
    }
    if (src->has_viewpoint && !dst->has_viewpoint) {
        dst->has_viewpoint = 1;
        for (int j = 0; j < 3; j++) dst->viewpoint[j] = src->viewpoint[j] + shift[j];
    }
    dst->normals_up |= src->normals_up;
    dst->npoints = total;
    return 0;
}

int rs_cloud_recentre(rs_cloud *c, double limit_m)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < c->npoints; i++)
        if (c->valid[i])
            for (int j = 0; j < 3; j++) {
                lo[j] = fmin(lo[j], c->xyz[3 * i + j]);
                hi[j] = fmax(hi[j], c->xyz[3 * i + j]);
            }
    for (int s = 0; s < c->nscans; s++)
        for (int j = 0; j < 3; j++) {
            lo[j] = fmin(lo[j], c->scans[s].position[j]);
            hi[j] = fmax(hi[j], c->scans[s].position[j]);
        }
    int far = 0;
    for (int j = 0; j < 3; j++) far |= lo[j] <= hi[j] && fmax(fabs(lo[j]), fabs(hi[j])) > limit_m;
    if (!far) return 0;
    /* Whole metres: the offset reads back exactly and points keep their sub-metre digits. */
    double shift[3];
    for (int j = 0; j < 3; j++) shift[j] = lo[j] <= hi[j] ? floor(0.5 * (lo[j] + hi[j]) + 0.5) : 0;
    for (size_t i = 0; i < c->npoints; i++)
        for (int j = 0; j < 3; j++) c->xyz[3 * i + j] -= shift[j];
    for (int s = 0; s < c->nscans; s++)
        for (int j = 0; j < 3; j++) c->scans[s].position[j] -= shift[j];
    for (int j = 0; j < 3; j++) {
        if (c->has_viewpoint) c->viewpoint[j] -= shift[j];
        c->origin[j] += shift[j];
    }
    return 1;
}

/* texture_raster: texels onto faces, points on faces, dilation of the gutters (texture_internal.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "stages/texture/texture_internal.h"

int rs_tex_pages_alloc(rs_tex_pages *t, const rs_mesh *m, const rs_atlas *a)
{
    memset(t, 0, sizeof *t);
    t->mesh = m;
    t->atlas = a;
    t->side = a->side;
    t->npages = a->npages;
    t->ntex = (size_t)a->npages * a->side * a->side;
    t->face = malloc(t->ntex * sizeof *t->face);
    t->rgb = calloc(3 * t->ntex, sizeof *t->rgb);
    t->sigma = calloc(t->ntex, sizeof *t->sigma);
    t->flags = calloc(t->ntex, 1);
    if (!t->face || !t->rgb || !t->sigma || !t->flags) return -1;
    for (size_t k = 0; k < t->ntex; k++) t->face[k] = -1;
    return 0;
}

void rs_tex_pages_free(rs_tex_pages *t)
{
    free(t->face);
    free(t->rgb);
    free(t->sigma);
    free(t->flags);
    memset(t, 0, sizeof *t);
}

/* Face f's corners in page pixel coordinates. */
static void face_xy(const rs_tex_pages *t, uint32_t f, double x[3], double y[3])
{
    for (int k = 0; k < 3; k++) {
        x[k] = t->atlas->uv[6 * (size_t)f + 2 * k] * (double)t->side;
        y[k] = t->atlas->uv[6 * (size_t)f + 2 * k + 1] * (double)t->side;
    }
}

/* Barycentrics of (px, py) in the triangle (x, y); 0 when it is degenerate. */
static int barycentric(const double *x, const double *y, double px, double py, double b[3])
{
    double d = (y[1] - y[2]) * (x[0] - x[2]) + (x[2] - x[1]) * (y[0] - y[2]);
    if (!(fabs(d) > 1e-12)) return 0;
    b[0] = ((y[1] - y[2]) * (px - x[2]) + (x[2] - x[1]) * (py - y[2])) / d;
    b[1] = ((y[2] - y[0]) * (px - x[2]) + (x[0] - x[2]) * (py - y[2])) / d;
    b[2] = 1 - b[0] - b[1];
    return 1;
}

rs_v3 rs_tex_point(const rs_tex_pages *t, uint32_t f, int x, int y, double b[3])
{
    double fx[3], fy[3];
    face_xy(t, f, fx, fy);
    if (!barycentric(fx, fy, x + 0.5, y + 0.5, b)) b[0] = b[1] = b[2] = 1.0 / 3;
    double s = 0;
    for (int k = 0; k < 3; k++) s += (b[k] = fmax(b[k], 0));
    for (int k = 0; k < 3; k++) b[k] /= s;
    const rs_mesh *m = t->mesh;
    rs_v3 p = rs_v3_make(0, 0, 0);
    for (int k = 0; k < 3; k++) p = rs_v3_add(p, rs_v3_scale(rs_mesh_vert(m, m->tris[3 * (size_t)f + k]), b[k]));
    return p;
}

/* The texels of one chart's faces, first face first. */
static size_t raster_chart(rs_tex_pages *t, const rs_atlas_chart *c)
{
    size_t n = 0, S = (size_t)t->side, base = (size_t)c->page * S * S;
    for (size_t q = c->first; q < c->first + c->count; q++) {
        uint32_t f = t->atlas->faces[q];
        double x[3], y[3], b[3];
        face_xy(t, f, x, y);
        int xa = (int)floor(fmin(x[0], fmin(x[1], x[2]))), xb = (int)ceil(fmax(x[0], fmax(x[1], x[2])));
        int ya = (int)floor(fmin(y[0], fmin(y[1], y[2]))), yb = (int)ceil(fmax(y[0], fmax(y[1], y[2])));
        for (int py = ya; py < yb; py++)
            for (int px = xa; px < xb; px++) {
                size_t k = base + (size_t)py * S + (size_t)px;
                if (t->face[k] >= 0 || !barycentric(x, y, px + 0.5, py + 0.5, b)) continue;
                const double e = -1e-9;
                if (b[0] < e || b[1] < e || b[2] < e) continue;
                t->face[k] = (int32_t)f;
                n++;
            }
    }
    /* The ring just outside: a neighbour's face, taken from the texels assigned above only. */
    static const int dx[8] = {1, -1, 0, 0, 1, -1, 1, -1}, dy[8] = {0, 0, 1, -1, 1, 1, -1, -1};
    int g = t->atlas->gutter;
    for (int py = c->y0 - 1; py <= c->y0 + c->h && g > 0; py++)
        for (int px = c->x0 - 1; px <= c->x0 + c->w; px++) {
            size_t k = base + (size_t)py * S + (size_t)px;
            if (t->face[k] >= 0) continue;
            for (int d = 0; d < 8; d++) {
                int qx = px + dx[d], qy = py + dy[d];
                if (qx < c->x0 || qy < c->y0 || qx >= c->x0 + c->w || qy >= c->y0 + c->h) continue;
                size_t kq = base + (size_t)qy * S + (size_t)qx;
                if (t->face[kq] >= 0 && !(t->flags[kq] & RS_TEX_EDGE)) {
                    t->face[k] = t->face[kq];
                    t->flags[k] |= RS_TEX_EDGE;
                    n++;
                    break;
                }
            }
        }
    return n;
}

size_t rs_tex_raster(rs_tex_pages *t)
{
    size_t n = 0;
    long nc = (long)t->atlas->ncharts;
#pragma omp parallel for schedule(dynamic, 16) reduction(+ : n)
    for (long ci = 0; ci < nc; ci++) n += raster_chart(t, &t->atlas->charts[ci]);
    return n;
}

/* One ring of dilation within the rectangle [x0, x1) x [y0, y1) of page p: every empty texel
 * with a filled 4-neighbour inside it (in filled, the rectangle's own) takes their mean. */
static size_t dilate_ring(rs_tex_pages *t, size_t base, int x0, int y0, int rw, int rh, uint8_t *filled, uint8_t *next)
{
    size_t S = (size_t)t->side, n = 0;
    memcpy(next, filled, (size_t)rw * rh);
    for (int y = 0; y < rh; y++)
        for (int x = 0; x < rw; x++) {
            size_t r = (size_t)y * rw + x;
            if (filled[r]) continue;
            float acc[3] = {0, 0, 0};
            int cnt = 0;
            static const int dx[4] = {-1, 1, 0, 0}, dy[4] = {0, 0, -1, 1};
            for (int d = 0; d < 4; d++) {
                int qx = x + dx[d], qy = y + dy[d];
                if (qx < 0 || qy < 0 || qx >= rw || qy >= rh || !filled[(size_t)qy * rw + qx]) continue;
                size_t k = base + (size_t)(y0 + qy) * S + (size_t)(x0 + qx);
                for (int ch = 0; ch < 3; ch++) acc[ch] += t->rgb[3 * k + ch];
                cnt++;
            }
            if (!cnt) continue;
            size_t k = base + (size_t)(y0 + y) * S + (size_t)(x0 + x);
            for (int ch = 0; ch < 3; ch++) t->rgb[3 * k + ch] = acc[ch] / cnt;
            t->flags[k] |= RS_TEX_GUTTER;
            next[r] = 1;
            n++;
        }
    memcpy(filled, next, (size_t)rw * rh);
    return n;
}

/* A chart's rectangle with its gutter, ring by ring from its texels. */
static void dilate_chart(rs_tex_pages *t, const rs_atlas_chart *c)
{
    int g = t->atlas->gutter, x0 = c->x0 - g, y0 = c->y0 - g, rw = c->w + 2 * g, rh = c->h + 2 * g;
    size_t S = (size_t)t->side, base = (size_t)c->page * S * S;
    uint8_t *filled = malloc((size_t)rw * rh), *next = malloc((size_t)rw * rh);
    if (filled && next) {
        for (int y = 0; y < rh; y++)
            for (int x = 0; x < rw; x++)
                filled[(size_t)y * rw + x] = t->face[base + (size_t)(y0 + y) * S + (size_t)(x0 + x)] >= 0;
        for (int r = 0; r < 2 * g + 2; r++)
            if (!dilate_ring(t, base, x0, y0, rw, rh, filled, next)) break;
    }
    free(filled);
    free(next);
}

void rs_tex_dilate(rs_tex_pages *t)
{
    size_t S = (size_t)t->side;
    long nc = (long)t->atlas->ncharts;
#pragma omp parallel for schedule(dynamic, 4)
    for (long ci = 0; ci < nc; ci++) dilate_chart(t, &t->atlas->charts[ci]);
    /* What no ring reached (between the charts' rectangles): the page's mean. */
    for (int p = 0; p < t->npages; p++) {
        size_t base = (size_t)p * S * S, nf = 0;
        double mean[3] = {0, 0, 0};
        for (size_t k = base; k < base + S * S; k++)
            if (t->face[k] >= 0) {
                for (int ch = 0; ch < 3; ch++) mean[ch] += t->rgb[3 * k + ch];
                nf++;
            }
        for (size_t k = base; k < base + S * S; k++)
            if (t->face[k] < 0 && !(t->flags[k] & RS_TEX_GUTTER)) {
                for (int ch = 0; ch < 3; ch++) t->rgb[3 * k + ch] = nf ? (float)(mean[ch] / nf) : 0;
                t->flags[k] |= RS_TEX_GUTTER;
            }
    }
}

void rs_tex_sample(const rs_tex_pages *t, int p, double u, double v, float rgb[3])
{
    int S = t->side;
    double X = u * S - 0.5, Y = v * S - 0.5;
    int x0 = (int)floor(X), y0 = (int)floor(Y);
    double fx = X - x0, fy = Y - y0;
    for (int ch = 0; ch < 3; ch++) rgb[ch] = 0;
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 2; i++) {
            int x = x0 + i < 0 ? 0 : (x0 + i >= S ? S - 1 : x0 + i);
            int y = y0 + j < 0 ? 0 : (y0 + j >= S ? S - 1 : y0 + j);
            double w = (i ? fx : 1 - fx) * (j ? fy : 1 - fy);
            const float *c = t->rgb + 3 * (((size_t)p * S + (size_t)y) * S + (size_t)x);
            for (int ch = 0; ch < 3; ch++) rgb[ch] += (float)(w * c[ch]);
        }
}

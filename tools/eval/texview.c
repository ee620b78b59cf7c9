/* rhoscan-texview: renders an albedo.glb's texture through its UVs into a camera's equirectangular
 * view, independently of the texture stage: it parses the GLB itself (cJSON for the JSON chunk),
 * turns glTF's Y-up positions back to Z-up (common/axes.h) and adds the root node's translation,
 * traces one ray per pixel centre (common/scene.h), interpolates the UVs of the hit triangle and
 * samples the primitive's baseColorTexture PNG bilinearly (decoded to linear). Writes an EXR with
 * R G B (the albedo the asset shows there) and hit (1 where a ray met the asset, else 0).
 *
 *     rhoscan-texview ALBEDO.glb WIDTH HEIGHT "PX PY PZ" "R00 ... R22" OUT.exr
 *
 * The pose is the camera's (docs/DESIGN.md, section Frames: local -> world, row-major). Used by
 * tools/eval/texture_eval.py. Exit 1 on a bad file or argument. */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/axes.h"
#include "common/fileio.h"
#include "common/image.h"
#include "common/pano.h"
#include "common/scene.h"

typedef struct {
    rs_mesh *mesh;
    float *uv;      /* 2 per vertex */
    int *face_img;  /* per face: image index */
    rs_image **img; /* decoded textures */
    int nimg;
} glb_model;

static const unsigned char *view_bytes(const cJSON *doc, const unsigned char *bin, size_t binlen, int vi, size_t *len)
{
    const cJSON *v = cJSON_GetArrayItem(cJSON_GetObjectItem(doc, "bufferViews"), vi);
    if (!v) return NULL;
    size_t off = (size_t)cJSON_GetNumberValue(cJSON_GetObjectItem(v, "byteOffset"));
    size_t n = (size_t)cJSON_GetNumberValue(cJSON_GetObjectItem(v, "byteLength"));
    if (!cJSON_GetObjectItem(v, "byteOffset")) off = 0;
    if (off + n > binlen) return NULL;
    *len = n;
    return bin + off;
}

/* The accessor's data as floats or uint32 (count x ncomp) into a new array. */
static void *accessor(const cJSON *doc, const unsigned char *bin, size_t binlen, int ai, int ncomp, size_t *count)
{
    const cJSON *a = cJSON_GetArrayItem(cJSON_GetObjectItem(doc, "accessors"), ai);
    if (!a) return NULL;
    size_t vlen = 0,
           off = cJSON_GetObjectItem(a, "byteOffset") ? (size_t)cJSON_GetObjectItem(a, "byteOffset")->valuedouble : 0;
    const unsigned char *vb = view_bytes(doc, bin, binlen, cJSON_GetObjectItem(a, "bufferView")->valueint, &vlen);
    int ct = cJSON_GetObjectItem(a, "componentType")->valueint;
    *count = (size_t)cJSON_GetObjectItem(a, "count")->valuedouble;
    size_t need = off + *count * ncomp * 4;
    if (!vb || (ct != 5126 && ct != 5125) || need > vlen) return NULL;
    void *out = malloc(*count * ncomp * 4 + 4);
    if (out) memcpy(out, vb + off, *count * ncomp * 4);
    return out;
}

static int load_glb(const char *path, glb_model *g)
{
    char *data = NULL;
    size_t n = 0;
    rs_err err = {0};
    if (rs_read_file(path, &data, &n, &err) != 0 || n < 28) return -1;
    uint32_t h[5];
    memcpy(h, data, sizeof h);
    if (h[0] != 0x46546C67u || h[1] != 2 || h[4] != 0x4E4F534Au || 20 + (size_t)h[3] + 8 > n) return -1;
    cJSON *doc = cJSON_ParseWithLength(data + 20, h[3]);
    const unsigned char *bin = (const unsigned char *)data + 20 + h[3] + 8;
    size_t binlen = n - (20 + h[3] + 8);
    const cJSON *node = cJSON_GetArrayItem(cJSON_GetObjectItem(doc, "nodes"), 0);
    double tr[3] = {0, 0, 0};
    const cJSON *t = cJSON_GetObjectItem(node, "translation");
    for (int k = 0; k < 3 && t; k++) tr[k] = cJSON_GetArrayItem(t, k)->valuedouble;
    const cJSON *prims = cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(doc, "meshes"), 0), "primitives");
    int np = cJSON_GetArraySize(prims), rc = 0;
    size_t nv = 0, nf = 0;
    float **pos = calloc((size_t)np, sizeof *pos), **uv = calloc((size_t)np, sizeof *uv);
    uint32_t **idx = calloc((size_t)np, sizeof *idx);
    size_t *pv = calloc((size_t)np, sizeof *pv), *pi = calloc((size_t)np, sizeof *pi);
    g->img = calloc((size_t)np, sizeof *g->img);
    g->nimg = np;
    for (int p = 0; p < np && rc == 0; p++) {
        const cJSON *pr = cJSON_GetArrayItem(prims, p), *at = cJSON_GetObjectItem(pr, "attributes");
        size_t cu = 0;
        pos[p] = accessor(doc, bin, binlen, cJSON_GetObjectItem(at, "POSITION")->valueint, 3, &pv[p]);
        uv[p] = accessor(doc, bin, binlen, cJSON_GetObjectItem(at, "TEXCOORD_0")->valueint, 2, &cu);
        idx[p] = accessor(doc, bin, binlen, cJSON_GetObjectItem(pr, "indices")->valueint, 1, &pi[p]);
        const cJSON *mat =
            cJSON_GetArrayItem(cJSON_GetObjectItem(doc, "materials"), cJSON_GetObjectItem(pr, "material")->valueint);
        int ti = cJSON_GetObjectItem(
                     cJSON_GetObjectItem(cJSON_GetObjectItem(mat, "pbrMetallicRoughness"), "baseColorTexture"), "index")
                     ->valueint;
        int ii = cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(doc, "textures"), ti), "source")->valueint;
        int bv =
            cJSON_GetObjectItem(cJSON_GetArrayItem(cJSON_GetObjectItem(doc, "images"), ii), "bufferView")->valueint;
        size_t plen = 0;
        const unsigned char *png = view_bytes(doc, bin, binlen, bv, &plen);
        if (!pos[p] || !uv[p] || !idx[p] || cu != pv[p] || !png ||
            !(g->img[p] = rs_image_read_mem(png, plen, "texture", &err)) || g->img[p]->channels != 3)
            rc = -1;
        nv += pv[p];
        nf += pi[p] / 3;
    }
    if (rc == 0 && (g->mesh = rs_mesh_new(nv, nf)) && (g->uv = malloc(2 * nv * sizeof *g->uv)) &&
        (g->face_img = malloc(nf * sizeof *g->face_img))) {
        size_t v0 = 0, f0 = 0;
        for (int p = 0; p < np; p++) {
            for (size_t v = 0; v < pv[p]; v++) {
                rs_v3 y = rs_v3_make(pos[p][3 * v] + tr[0], pos[p][3 * v + 1] + tr[1], pos[p][3 * v + 2] + tr[2]);
                rs_v3 z = rs_axes_zup_from_yup(y);
                float *o = g->mesh->verts + 3 * (v0 + v);
                o[0] = (float)z.x, o[1] = (float)z.y, o[2] = (float)z.z;
                memcpy(g->uv + 2 * (v0 + v), uv[p] + 2 * v, 2 * sizeof(float));
            }
            for (size_t f = 0; f < pi[p] / 3; f++) {
                for (int k = 0; k < 3; k++) {
                    if (idx[p][3 * f + k] >= pv[p]) rc = -1;
                    g->mesh->tris[3 * (f0 + f) + k] = (uint32_t)(v0 + (idx[p][3 * f + k] % (pv[p] ? pv[p] : 1)));
                }
                g->face_img[f0 + f] = p;
            }
            v0 += pv[p];
            f0 += pi[p] / 3;
        }
    } else
        rc = -1;
    for (int p = 0; p < np; p++) {
        free(pos[p]);
        free(uv[p]);
        free(idx[p]);
    }
    free(pos);
    free(uv);
    free(idx);
    free(pv);
    free(pi);
    cJSON_Delete(doc);
    free(data);
    return rc;
}

int main(int argc, char **argv)
{
    if (argc != 7) {
        fprintf(stderr, "usage: rhoscan-texview ALBEDO.glb WIDTH HEIGHT \"PX PY PZ\" \"R00 ... R22\" OUT.exr\n");
        return 1;
    }
    int W = atoi(argv[2]), H = atoi(argv[3]);
    rs_pose pose;
    if (W < 2 || H < 1 || sscanf(argv[4], "%lf %lf %lf", &pose.position.x, &pose.position.y, &pose.position.z) != 3) {
        fprintf(stderr, "rhoscan-texview: bad size or position\n");
        return 1;
    }
    double *r = pose.rot;
    if (sscanf(argv[5], "%lf %lf %lf %lf %lf %lf %lf %lf %lf", r, r + 1, r + 2, r + 3, r + 4, r + 5, r + 6, r + 7,
               r + 8) != 9) {
        fprintf(stderr, "rhoscan-texview: the rotation needs 9 numbers\n");
        return 1;
    }
    glb_model g = {0};
    if (load_glb(argv[1], &g) != 0) {
        fprintf(stderr, "rhoscan-texview: %s: not a GLB as the texture stage writes it\n", argv[1]);
        return 1;
    }
    rs_err err = {0};
    rs_scene *sc = rs_scene_new(g.mesh, &err);
    rs_image *out = rs_image_new(W, H, 4);
    if (!sc || !out) {
        fprintf(stderr, "rhoscan-texview: %s\n", err.msg);
        return 2;
    }
#pragma omp parallel for schedule(dynamic, 4)
    for (int y = 0; y < H; y++) {
        rs_ray *rays = malloc((size_t)W * sizeof *rays);
        rs_hit *hits = malloc((size_t)W * sizeof *hits);
        for (int x = 0; x < W; x++)
            rays[x] = (rs_ray){pose.position, rs_pose_dir_to_world(&pose, rs_pano_pixel_dir(W, H, x, y)), 0, INFINITY};
        rs_scene_intersect(sc, rays, hits, (size_t)W);
        for (int x = 0; x < W; x++) {
            float *o = rs_image_px(out, x, y);
            if (hits[x].face == RS_NO_HIT) continue;
            uint32_t f = hits[x].face;
            const uint32_t *t = g.mesh->tris + 3 * (size_t)f;
            double b1 = hits[x].u, b2 = hits[x].v, b0 = 1 - b1 - b2;
            double u = b0 * g.uv[2 * t[0]] + b1 * g.uv[2 * t[1]] + b2 * g.uv[2 * t[2]];
            double v = b0 * g.uv[2 * t[0] + 1] + b1 * g.uv[2 * t[1] + 1] + b2 * g.uv[2 * t[2] + 1];
            const rs_image *im = g.img[g.face_img[f]];
            double X = u * im->width - 0.5, Y = v * im->height - 0.5;
            int x0 = (int)floor(X), y0 = (int)floor(Y);
            double fx = X - x0, fy = Y - y0;
            for (int j = 0; j < 2; j++)
                for (int i = 0; i < 2; i++) {
                    int xx = x0 + i < 0 ? 0 : (x0 + i >= im->width ? im->width - 1 : x0 + i);
                    int yy = y0 + j < 0 ? 0 : (y0 + j >= im->height ? im->height - 1 : y0 + j);
                    double w = (i ? fx : 1 - fx) * (j ? fy : 1 - fy);
                    for (int c = 0; c < 3; c++) o[c] += (float)(w * rs_image_px(im, xx, yy)[c]);
                }
            o[3] = 1;
        }
        free(rays);
        free(hits);
    }
    static const char *const names[] = {"R", "G", "B", "hit"};
    int rc = rs_image_write_exr(out, argv[6], names, 0, "rhoscan-texview", &err) == 0 ? 0 : 2;
    if (rc) fprintf(stderr, "rhoscan-texview: %s\n", err.msg);
    rs_image_free(out);
    rs_scene_free(sc);
    return rc;
}

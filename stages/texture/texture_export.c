/* texture_export: the textured model for viewers (issue 22, part 3). Vertices are split per
 * chart (a vertex of two charts has two UVs, and colours must not bleed across the edge); faces
 * are grouped by page, one glTF primitive and one OBJ material per page.
 * - albedo.glb: glTF 2.0 binary written here (the container is a JSON chunk and a BIN chunk;
 *   cJSON builds the JSON): POSITION (with min/max), TEXCOORD_0, uint32 indices, a
 *   metallic-roughness material per page with baseColorTexture (the page's sRGB PNG, embedded),
 *   metallic 0, roughness 1; Y up (common/axes.h), rhoscan_origin as the root node's translation.
 * - albedo.obj + albedo.mtl: Y up like glTF, triangles, map_Kd the page's PNG; the origin in the
 *   header comment.
 * - albedo_vertex.ply: rhoscan's frame, per vertex uchar sRGB red green blue and the linear float
 *   albedo_r/_g/_b, sampled from the texture at the vertex. */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/axes.h"
#include "common/fileio.h"
#include "common/image.h"
#include "common/ply.h"
#include "pipeline/stage.h"
#include "stages/texture/texture_internal.h"

typedef struct {
    uint32_t page, chart, vertex, corner; /* corner: 3 f + k */
} split_rec;

static int split_cmp(const void *a, const void *b)
{
    const split_rec *x = a, *y = b;
    if (x->page != y->page) return x->page < y->page ? -1 : 1;
    if (x->chart != y->chart) return x->chart < y->chart ? -1 : 1;
    if (x->vertex != y->vertex) return x->vertex < y->vertex ? -1 : 1;
    return (x->corner > y->corner) - (x->corner < y->corner);
}

/* The split model: nv vertices (pos: 3, uv: 2, rgb: 3 linear each), page of each, and per page
 * its faces (tris, indices into the split vertices) and first vertex. */
typedef struct {
    size_t nv, nf;
    float *pos, *uv, *rgb;
    uint32_t *tris; /* 3 per face, faces grouped by page */
    size_t *vstart; /* npages + 1 */
    size_t *fstart; /* npages + 1 */
} split_model;

static void split_free(split_model *s)
{
    free(s->pos);
    free(s->uv);
    free(s->rgb);
    free(s->tris);
    free(s->vstart);
    free(s->fstart);
}

static int split_build(const rs_tex_pages *t, split_model *s)
{
    const rs_mesh *m = t->mesh;
    const rs_atlas *a = t->atlas;
    size_t nc = 3 * m->nfaces, P = (size_t)t->npages;
    memset(s, 0, sizeof *s);
    split_rec *r = malloc(nc * sizeof *r);
    uint32_t *cidx = malloc(nc * sizeof *cidx);
    s->vstart = calloc(P + 1, sizeof *s->vstart);
    s->fstart = calloc(P + 1, sizeof *s->fstart);
    s->pos = malloc(3 * nc * sizeof *s->pos);
    s->uv = malloc(2 * nc * sizeof *s->uv);
    s->rgb = malloc(3 * nc * sizeof *s->rgb);
    s->tris = malloc(nc * sizeof *s->tris);
    int ok = r && cidx && s->vstart && s->fstart && s->pos && s->uv && s->rgb && s->tris;
    if (ok) {
        for (size_t c = 0; c < nc; c++) {
            uint32_t ch = a->face_chart[c / 3];
            r[c] = (split_rec){(uint32_t)a->charts[ch].page, ch, m->tris[c], (uint32_t)c};
        }
        qsort(r, nc, sizeof *r, split_cmp);
        for (size_t i = 0; i < nc;) {
            size_t j = i, v = s->nv++;
            for (; j < nc && r[j].chart == r[i].chart && r[j].vertex == r[i].vertex; j++)
                cidx[r[j].corner] = (uint32_t)v;
            for (int q = 0; q < 3; q++) s->pos[3 * v + q] = m->verts[3 * (size_t)r[i].vertex + q];
            memcpy(s->uv + 2 * v, a->uv + 2 * (size_t)r[i].corner, 2 * sizeof(float));
            rs_tex_sample(t, (int)r[i].page, s->uv[2 * v], s->uv[2 * v + 1], s->rgb + 3 * v);
            s->vstart[r[i].page + 1] = s->nv;
            i = j;
        }
        for (size_t p = 1; p <= P; p++)
            if (s->vstart[p] < s->vstart[p - 1]) s->vstart[p] = s->vstart[p - 1];
        /* faces by page, in face order within a page */
        for (size_t f = 0; f < m->nfaces; f++) s->fstart[a->charts[a->face_chart[f]].page + 1]++;
        for (size_t p = 1; p <= P; p++) s->fstart[p] += s->fstart[p - 1];
        size_t *fill = malloc((P + 1) * sizeof *fill);
        if ((ok = fill != NULL)) {
            memcpy(fill, s->fstart, (P + 1) * sizeof *fill);
            for (size_t f = 0; f < m->nfaces; f++) {
                size_t d = fill[a->charts[a->face_chart[f]].page]++;
                for (int k = 0; k < 3; k++) s->tris[3 * d + k] = cidx[3 * f + k];
            }
            s->nf = m->nfaces;
        }
        free(fill);
    }
    free(r);
    free(cidx);
    return ok ? 0 : -1;
}

/* ---- albedo.glb ---- */

typedef struct {
    unsigned char *data;
    size_t len, cap;
} bytes;

static int bytes_put(bytes *b, const void *p, size_t n)
{
    if (b->len + n + 4 > b->cap) {
        size_t cap = (b->len + n + 4) * 2;
        unsigned char *d = realloc(b->data, cap);
        if (!d) return -1;
        b->data = d;
        b->cap = cap;
    }
    if (n) memcpy(b->data + b->len, p, n);
    b->len += n;
    return 0;
}

static int bytes_pad(bytes *b, unsigned char c)
{
    while (b->len % 4)
        if (bytes_put(b, &c, 1) != 0) return -1;
    return 0;
}

static cJSON *view(cJSON *views, size_t off, size_t len, int target)
{
    cJSON *v = cJSON_CreateObject();
    cJSON_AddNumberToObject(v, "buffer", 0);
    cJSON_AddNumberToObject(v, "byteOffset", (double)off);
    cJSON_AddNumberToObject(v, "byteLength", (double)len);
    if (target) cJSON_AddNumberToObject(v, "target", target);
    cJSON_AddItemToArray(views, v);
    return v;
}

static int accessor(cJSON *accs, int view_index, size_t off, int ctype, size_t count, const char *type)
{
    cJSON *a = cJSON_CreateObject();
    cJSON_AddNumberToObject(a, "bufferView", view_index);
    cJSON_AddNumberToObject(a, "byteOffset", (double)off);
    cJSON_AddNumberToObject(a, "componentType", ctype);
    cJSON_AddNumberToObject(a, "count", (double)count);
    cJSON_AddStringToObject(a, "type", type);
    cJSON_AddItemToArray(accs, a);
    return cJSON_GetArraySize(accs) - 1;
}

/* The JSON of the glb: every per-page object; bin holds the buffer's layout already. */
static cJSON *gltf_json(const split_model *s, const rs_tex_export *e, const size_t *png_off, const size_t *png_len,
                        size_t bin_len, const float *yup)
{
    int P = e->pages->npages;
    cJSON *root = cJSON_CreateObject(), *asset = cJSON_AddObjectToObject(root, "asset");
    cJSON_AddStringToObject(asset, "version", "2.0");
    cJSON_AddStringToObject(asset, "generator", "rhoscan " RHOSCAN_VERSION " (texture stage)");
    cJSON_AddNumberToObject(root, "scene", 0);
    cJSON *scn = cJSON_CreateObject(), *nodes = cJSON_AddArrayToObject(root, "nodes");
    cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "scenes"), scn);
    cJSON_AddItemToArray(cJSON_AddArrayToObject(scn, "nodes"), cJSON_CreateNumber(0));
    cJSON *node = cJSON_CreateObject();
    cJSON_AddStringToObject(node, "name", "rhoscan_model");
    cJSON_AddNumberToObject(node, "mesh", 0);
    rs_v3 o = rs_axes_yup_from_zup(rs_v3_make(e->origin[0], e->origin[1], e->origin[2]));
    double ot[3] = {o.x, o.y, o.z};
    cJSON_AddItemToObject(node, "translation", cJSON_CreateDoubleArray(ot, 3));
    cJSON_AddItemToArray(nodes, node);
    cJSON *bufs = cJSON_AddArrayToObject(root, "buffers"), *buf = cJSON_CreateObject();
    cJSON_AddNumberToObject(buf, "byteLength", (double)bin_len);
    cJSON_AddItemToArray(bufs, buf);
    cJSON *views = cJSON_AddArrayToObject(root, "bufferViews"), *accs = cJSON_AddArrayToObject(root, "accessors");
    size_t nv = s->nv;
    view(views, 0, 12 * nv, 34962);
    view(views, 12 * nv, 8 * nv, 34962);
    view(views, 20 * nv, 12 * s->nf, 34963);
    cJSON *mats = cJSON_AddArrayToObject(root, "materials"), *texs = cJSON_AddArrayToObject(root, "textures");
    cJSON *imgs = cJSON_AddArrayToObject(root, "images"), *smp = cJSON_CreateObject();
    cJSON_AddNumberToObject(smp, "magFilter", 9729); /* LINEAR */
    cJSON_AddNumberToObject(smp, "minFilter", 9987); /* LINEAR_MIPMAP_LINEAR */
    cJSON_AddNumberToObject(smp, "wrapS", 33071);    /* CLAMP_TO_EDGE */
    cJSON_AddNumberToObject(smp, "wrapT", 33071);
    cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "samplers"), smp);
    cJSON *mesh = cJSON_CreateObject(), *prims = cJSON_AddArrayToObject(mesh, "primitives");
    cJSON_AddStringToObject(mesh, "name", "albedo");
    cJSON_AddItemToArray(cJSON_AddArrayToObject(root, "meshes"), mesh);
    for (int p = 0; p < P; p++) {
        size_t v0 = s->vstart[p], v1 = s->vstart[p + 1], f0 = s->fstart[p], f1 = s->fstart[p + 1];
        if (v1 == v0 || f1 == f0) continue;
        int ia = accessor(accs, 0, 12 * v0, 5126, v1 - v0, "VEC3");
        double mn[3] = {INFINITY, INFINITY, INFINITY}, mx[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t v = v0; v < v1; v++)
            for (int q = 0; q < 3; q++) {
                mn[q] = fmin(mn[q], yup[3 * v + q]);
                mx[q] = fmax(mx[q], yup[3 * v + q]);
            }
        cJSON *pa = cJSON_GetArrayItem(accs, ia);
        cJSON_AddItemToObject(pa, "min", cJSON_CreateDoubleArray(mn, 3));
        cJSON_AddItemToObject(pa, "max", cJSON_CreateDoubleArray(mx, 3));
        int it = accessor(accs, 1, 8 * v0, 5126, v1 - v0, "VEC2");
        int ii = accessor(accs, 2, 12 * f0, 5125, 3 * (f1 - f0), "SCALAR");
        cJSON *img = cJSON_CreateObject();
        cJSON_AddNumberToObject(img, "bufferView", cJSON_GetArraySize(views));
        cJSON_AddStringToObject(img, "mimeType", "image/png");
        cJSON_AddStringToObject(img, "name", e->png_names[p]);
        view(views, png_off[p], png_len[p], 0);
        cJSON_AddItemToArray(imgs, img);
        cJSON *tex = cJSON_CreateObject();
        cJSON_AddNumberToObject(tex, "sampler", 0);
        cJSON_AddNumberToObject(tex, "source", cJSON_GetArraySize(imgs) - 1);
        cJSON_AddItemToArray(texs, tex);
        cJSON *mat = cJSON_CreateObject(), *pbr = cJSON_AddObjectToObject(mat, "pbrMetallicRoughness");
        char name[64];
        snprintf(name, sizeof name, "albedo_page_%d", p);
        cJSON_AddStringToObject(mat, "name", name);
        cJSON_AddNumberToObject(cJSON_AddObjectToObject(pbr, "baseColorTexture"), "index",
                                cJSON_GetArraySize(texs) - 1);
        cJSON_AddNumberToObject(pbr, "metallicFactor", 0);
        cJSON_AddNumberToObject(pbr, "roughnessFactor", 1);
        cJSON_AddItemToArray(mats, mat);
        cJSON *prim = cJSON_CreateObject(), *attr = cJSON_AddObjectToObject(prim, "attributes");
        cJSON_AddNumberToObject(attr, "POSITION", ia);
        cJSON_AddNumberToObject(attr, "TEXCOORD_0", it);
        cJSON_AddNumberToObject(prim, "indices", ii);
        cJSON_AddNumberToObject(prim, "material", cJSON_GetArraySize(mats) - 1);
        cJSON_AddNumberToObject(prim, "mode", 4);
        cJSON_AddItemToArray(prims, prim);
    }
    return root;
}

/* The BIN chunk: positions (Y up), UVs, indices relative to each page's first vertex, PNGs. */
static int gltf_bin(const split_model *s, const rs_tex_export *e, bytes *bin, size_t *png_off, size_t *png_len,
                    float *yup, rs_err *err)
{
    for (size_t v = 0; v < s->nv; v++) {
        rs_v3 y = rs_axes_yup_from_zup(rs_v3_from_f(s->pos + 3 * v));
        yup[3 * v] = (float)y.x;
        yup[3 * v + 1] = (float)y.y;
        yup[3 * v + 2] = (float)y.z;
    }
    if (bytes_put(bin, yup, 12 * s->nv) || bytes_put(bin, s->uv, 8 * s->nv)) return -1;
    for (int p = 0; p < e->pages->npages; p++)
        for (size_t f = s->fstart[p]; f < s->fstart[p + 1]; f++)
            for (int k = 0; k < 3; k++) {
                uint32_t i = s->tris[3 * f + k] - (uint32_t)s->vstart[p];
                if (bytes_put(bin, &i, 4)) return -1;
            }
    for (int p = 0; p < e->pages->npages; p++) {
        char path[4096], *png = NULL;
        size_t n = 0;
        if (rs_read_file(rs_work_path(e->cfg, e->png_names[p], path, sizeof path), &png, &n, err) != 0) return -2;
        png_off[p] = bin->len;
        png_len[p] = n;
        int rc = bytes_put(bin, png, n) || bytes_pad(bin, 0);
        free(png);
        if (rc) return -1;
    }
    return bytes_pad(bin, 0);
}

static int write_glb(const split_model *s, const rs_tex_export *e, rs_err *err)
{
    int P = e->pages->npages, rc = -1;
    bytes bin = {0}, out = {0};
    size_t *po = calloc((size_t)P, sizeof *po), *pl = calloc((size_t)P, sizeof *pl);
    float *yup = malloc((3 * s->nv + 1) * sizeof *yup);
    char *json = NULL;
    cJSON *root = NULL;
    if (!po || !pl || !yup) goto oom;
    int b = gltf_bin(s, e, &bin, po, pl, yup, err);
    if (b == -2) goto out;
    if (b != 0) goto oom;
    if (!(root = gltf_json(s, e, po, pl, bin.len, yup)) || !(json = cJSON_PrintUnformatted(root))) goto oom;
    size_t jl = strlen(json), jpad = (4 - jl % 4) % 4;
    uint32_t hdr[5] = {0x46546C67u, 2, (uint32_t)(12 + 8 + jl + jpad + 8 + bin.len), (uint32_t)(jl + jpad),
                       0x4E4F534Au};
    uint32_t bh[2] = {(uint32_t)bin.len, 0x004E4942u};
    if (bytes_put(&out, hdr, sizeof hdr) || bytes_put(&out, json, jl) || bytes_pad(&out, ' ') ||
        bytes_put(&out, bh, sizeof bh) || bytes_put(&out, bin.data, bin.len))
        goto oom;
    char path[4096];
    rc = rs_write_file_atomic(rs_work_path(e->cfg, "albedo.glb", path, sizeof path), out.data, out.len, err);
    goto out;
oom:
    rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory writing albedo.glb");
out:
    cJSON_Delete(root);
    free(json);
    free(bin.data);
    free(out.data);
    free(po);
    free(pl);
    free(yup);
    return rc;
}

/* ---- albedo.obj, albedo.mtl ---- */

static int put_text(rs_atomic_file *f, rs_err *err, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static int put_text(rs_atomic_file *f, rs_err *err, const char *fmt, ...)
{
    char line[512];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    return rs_atomic_write(f, line, (size_t)(n < (int)sizeof line ? n : (int)sizeof line - 1), err);
}

static int write_obj(const split_model *s, const rs_tex_export *e, rs_err *err)
{
    char path[4096];
    rs_atomic_file f;
    if (rs_atomic_open(&f, rs_work_path(e->cfg, "albedo.mtl", path, sizeof path), err) != 0) return -1;
    int bad = put_text(&f, err, "# rhoscan albedo texture materials (texture stage)\n");
    for (int p = 0; p < e->pages->npages && !bad; p++)
        bad = put_text(&f, err, "newmtl albedo_page_%d\nKa 0 0 0\nKd 1 1 1\nKs 0 0 0\nd 1\nillum 1\nmap_Kd %s\n\n", p,
                       e->png_names[p]);
    if (bad || rs_atomic_commit(&f, err) != 0) {
        rs_atomic_abort(&f);
        return -1;
    }
    if (rs_atomic_open(&f, rs_work_path(e->cfg, "albedo.obj", path, sizeof path), err) != 0) return -1;
    bad = put_text(&f, err,
                   "# rhoscan albedo (texture stage): metres, Y up (rhoscan's x, z, -y), triangles\n"
                   "# rhoscan_origin %.17g %.17g %.17g (world = file + origin, in rhoscan's Z-up frame)\n"
                   "mtllib albedo.mtl\n",
                   e->origin[0], e->origin[1], e->origin[2]);
    for (size_t v = 0; v < s->nv && !bad; v++) {
        rs_v3 y = rs_axes_yup_from_zup(rs_v3_from_f(s->pos + 3 * v));
        bad = put_text(&f, err, "v %.9g %.9g %.9g\n", y.x, y.y, y.z);
    }
    for (size_t v = 0; v < s->nv && !bad; v++) /* OBJ's v grows upward */
        bad = put_text(&f, err, "vt %.9g %.9g\n", s->uv[2 * v], 1.0 - s->uv[2 * v + 1]);
    for (int p = 0; p < e->pages->npages && !bad; p++) {
        bad = put_text(&f, err, "usemtl albedo_page_%d\n", p);
        for (size_t q = s->fstart[p]; q < s->fstart[p + 1] && !bad; q++) {
            uint32_t a = s->tris[3 * q] + 1, b = s->tris[3 * q + 1] + 1, c = s->tris[3 * q + 2] + 1;
            bad = put_text(&f, err, "f %u/%u %u/%u %u/%u\n", a, a, b, b, c, c);
        }
    }
    if (bad || rs_atomic_commit(&f, err) != 0) {
        rs_atomic_abort(&f);
        return -1;
    }
    return 0;
}

/* ---- albedo_vertex.ply ---- */

static int write_vertex_ply(const split_model *s, const rs_tex_export *e, rs_err *err)
{
    rs_mesh *m = rs_mesh_new(s->nv, s->nf);
    rs_ply *ply = rs_ply_new();
    float *col = malloc((s->nv + 1) * sizeof *col);
    int rc = -1;
    if (!m || !ply || !col) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory writing albedo_vertex.ply");
        goto out;
    }
    memcpy(m->verts, s->pos, 3 * s->nv * sizeof(float));
    memcpy(m->tris, s->tris, 3 * s->nf * sizeof(uint32_t));
    rs_ply_add_comment(ply,
                       "rhoscan albedo per vertex (texture stage): red green blue are the albedo clipped to "
                       "[0, 1], sRGB-encoded 8-bit; albedo_r/_g/_b linear floats; vertices split per chart");
    if (e->origin[0] || e->origin[1] || e->origin[2])
        rs_ply_add_comment(ply, "rhoscan_origin %.17g %.17g %.17g", e->origin[0], e->origin[1], e->origin[2]);
    rs_mesh_to_ply(m, ply);
    rs_ply_element *ve = rs_ply_find_element(ply, "vertex");
    static const char *const u8[3] = {"red", "green", "blue"}, *const fl[3] = {"albedo_r", "albedo_g", "albedo_b"};
    for (int q = 0; q < 3 && ve; q++) {
        for (size_t v = 0; v < s->nv; v++) {
            float x = s->rgb[3 * v + q];
            x = x > 0 ? (x < 1 ? x : 1) : 0;
            col[v] = floorf(rs_linear_to_srgb(x) * 255.0f + 0.5f);
        }
        if (!rs_ply_add_scalar_f(ve, u8[q], RS_PLY_UINT8, col)) ve = NULL;
    }
    for (int q = 0; q < 3 && ve; q++) {
        for (size_t v = 0; v < s->nv; v++) col[v] = s->rgb[3 * v + q];
        if (!rs_ply_add_scalar_f(ve, fl[q], RS_PLY_FLOAT32, col)) ve = NULL;
    }
    if (!ve) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory writing albedo_vertex.ply");
        goto out;
    }
    char path[4096];
    rc = rs_ply_write(ply, rs_work_path(e->cfg, "albedo_vertex.ply", path, sizeof path), 1, err);
out:
    free(col);
    rs_ply_free(ply);
    rs_mesh_free(m);
    return rc;
}

int rs_tex_export_all(rs_tex_export *e, rs_err *err)
{
    split_model s;
    if (split_build(e->pages, &s) != 0) {
        split_free(&s);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory splitting the textured model's vertices");
    }
    e->vertices = s.nv;
    int rc = write_glb(&s, e, err) == 0 && write_obj(&s, e, err) == 0 && write_vertex_ply(&s, e, err) == 0 ? 0 : -1;
    split_free(&s);
    return rc;
}

/* texture: the per-texel albedo (issue 22). On the atlas of the mesh (meshing/atlas.h), every
 * texel's point x on the surface gets
 *     rho(x) = pi L(x) / E(x),   E(x) = D(x) + U_chart cos(n, s) V(x)
 * L(x): the capture's panorama where a ray from the camera reaches x unoccluded and x faces it,
 *   sampled bilinearly at sub-texel points (as many as a panorama pixel's footprint needs, up
 *   to 3 x 3) whose four pixels all see the same chart (facet_id.exr): nothing from another
 *   surface or the sky leaks in;
 * D(x): the sky (without the sun) and interreflected irradiance of the facets (irradiance.ply's
 *   irradiance_sky - irradiance_sun, albedo.ply's irradiance_inter), averaged at each corner over
 *   the chart's faces meeting there and interpolated barycentrically: no step between facets;
 * V(x): the share of shadow rays toward the sun's disc that escape, per texel; U_chart the sun's
 *   normal irradiance that makes the chart's sun power equal the facets' (sum A_f E_sun,f /
 *   sum A_f cos_f V_f, V_f the facet's mean texel V). A texel the shadow's edge crosses
 *   (0 < V < 1) is flagged. The sun's direction is irradiance.json's `sun_direction`; the shadow
 *   rays see the occluders the irradiance stage closed the model with (its `occluders`), as its
 *   facets' sun did.
 * Texels no capture sees take their facet's solved albedo. Outputs: albedo_texture.exr (R G B,
 * linear), albedo_texture_flags.exr (flags, sigma) and albedo_texture.png (sRGB) per page
 * (albedo_texture_P.* with several), and the exports (texture_export.c). */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "common/capture.h"
#include "common/faceprop.h"
#include "common/fileio.h"
#include "common/log.h"
#include "common/par.h"
#include "common/scene.h"
#include "common/select.h"
#include "meshing/occluders_ply.h"
#include "pipeline/capture_load.h"
#include "sky/skyenv.h"
#include "stages/stages.h"
#include "stages/texture/texture_internal.h"

#define SUN_RAYS       4
#define SUN_RADIUS_RAD (0.2665 * M_PI / 180)
#define TEX_SEEN       128u                       /* while the texels are measured: a capture saw the texel */
#define TEX_FURTHER    64u                        /* and a further capture saw it */
#define TEX_MAX_VIEWS  (RS_SKYENV_MAX_OTHERS + 1) /* [capture] and the further captures the sky map takes */

/* A capture that measures L: [capture] (view 0) or a further [capture.NAME]. */
typedef struct {
    rs_capture cap;
    rs_image *ids;   /* the facet under each pixel's centre, -1 none: facet_id.exr for [capture], traced for
                        the others (trace_ids) */
    double scale[3]; /* to [capture]'s exposure: irradiance.json's capture_exposure (1 for [capture]) */
    const char *name;
} tex_view;

typedef struct {
    rs_mesh *mesh;
    rs_ply *alb, *irr;
    size_t nf;
    double *rho, *esky, *esun, *G; /* 3 per facet */
    double *estimable;             /* per facet */
    double *unobserved;            /* per facet, with further captures only (else NULL): 1 when [capture] did not
                                      observe it (no facet albedo) but the irradiance stage gathered its light */
    tex_view views[TEX_MAX_VIEWS];
    int nviews;
    rs_v3 sun;    /* toward the sun; zero when none */
    rs_mesh *occ; /* the irradiance stage's occluders (irradiance.json's occluders), NULL when it had none */
    uint32_t *occ_proxy;
    double occ_near; /* their near limit, m, as the irradiance stage attached them */
    double origin[3];
} tex_inputs;

static void tex_inputs_free(tex_inputs *in)
{
    rs_mesh_free(in->mesh);
    rs_ply_free(in->alb);
    rs_ply_free(in->irr);
    free(in->rho);
    free(in->esky);
    free(in->esun);
    free(in->G);
    free(in->estimable);
    free(in->unobserved);
    rs_mesh_free(in->occ);
    free(in->occ_proxy);
    for (int v = 0; v < in->nviews; v++) {
        rs_capture_release(&in->views[v].cap);
        rs_image_free(in->views[v].ids);
    }
}

/* irradiance.json, parsed (NULL when absent or unreadable). */
static cJSON *read_irradiance_json(const rs_config *cfg)
{
    char path[4096], *text = NULL;
    size_t n = 0;
    if (rs_read_file(rs_work_path(cfg, "irradiance.json", path, sizeof path), &text, &n, NULL) != 0) return NULL;
    cJSON *j = cJSON_ParseWithLength(text, n);
    free(text);
    return j;
}

/* irradiance.json's sun_direction (zero when absent or not a unit vector). */
static rs_v3 read_sun_direction(const cJSON *j)
{
    rs_v3 s = rs_v3_make(0, 0, 0);
    const cJSON *d = cJSON_GetObjectItemCaseSensitive(j, "sun_direction");
    if (cJSON_IsArray(d) && cJSON_GetArraySize(d) == 3) {
        rs_v3 v = rs_v3_make(cJSON_GetArrayItem(d, 0)->valuedouble, cJSON_GetArrayItem(d, 1)->valuedouble,
                             cJSON_GetArrayItem(d, 2)->valuedouble);
        if (rs_v3_finite(v) && fabs(rs_v3_len(v) - 1) < 1e-3) s = rs_v3_norm(v);
    }
    return s;
}

/* The occluders the irradiance stage attached to its scene (irradiance.json's `occluders`: mode,
 * faces, near_m): occluders.ply in the work folder, or [irradiance] occluders_file with
 * occluders = file. Its facets' sun (irradiance_sun) was shadowed by them, so the texels' shadow
 * rays must be too, or the chart's sun power (chart_sun) would be spread onto texels the
 * occluders shade. None (in->occ NULL) when it attached none. */
static int read_occluders(const rs_config *cfg, const cJSON *irr, tex_inputs *in, rs_err *err)
{
    const cJSON *o = cJSON_GetObjectItemCaseSensitive(irr, "occluders");
    const cJSON *faces = cJSON_GetObjectItemCaseSensitive(o, "faces"),
                *near = cJSON_GetObjectItemCaseSensitive(o, "near_m"),
                *mode = cJSON_GetObjectItemCaseSensitive(o, "mode");
    if (!cJSON_IsNumber(faces) || !(faces->valuedouble > 0)) return 0;
    char path[4096], jp[4096];
    rs_work_path(cfg, "irradiance.json", jp, sizeof jp);
    if (!cJSON_IsNumber(near) || !(near->valuedouble >= 0) || !isfinite(near->valuedouble) || !cJSON_IsString(mode))
        return rs_err_set(err, RS_ERR_INPUT, jp, 0,
                          "occluders: expected mode and near_m (a distance >= 0) with faces > 0 (rerun irradiance)");
    const char *fp = strcmp(mode->valuestring, "file") == 0
        ? rs_config_path(cfg, "irradiance", "occluders_file", path, sizeof path)
        : rs_work_path(cfg, "occluders.ply", path, sizeof path);
    if (!fp)
        return rs_err_set(err, RS_ERR_INPUT, jp, 0,
                          "occluders: mode file, but [irradiance] occluders_file is not set (rerun irradiance)");
    if (rs_occluders_read(fp, in->nf, &in->occ, &in->occ_proxy, err) != 0) return -1;
    if ((double)in->occ->nfaces != faces->valuedouble)
        return rs_err_set(err, RS_ERR_INPUT, fp, 0, "%zu faces, irradiance.json's occluders has %g: rerun irradiance",
                          in->occ->nfaces, faces->valuedouble);
    in->occ_near = near->valuedouble;
    return 0;
}

/* The further captures ([capture.NAME], in file order, as many as the irradiance stage's sky map
 * takes), each with the exposure factor that stage found for it from the sky both saw
 * (irradiance.json's capture_exposure, skyenv.h): their radiance is brought to [capture]'s
 * exposure the same way as their sky. */
static int load_further_views(const rs_config *cfg, const cJSON *irr, tex_inputs *in, rs_err *err)
{
    const char *names[TEX_MAX_VIEWS];
    int n = rs_config_sections(cfg, "capture", names, TEX_MAX_VIEWS);
    const cJSON *ce = cJSON_GetObjectItemCaseSensitive(irr, "capture_exposure");
    for (int i = 0; i < n && i < TEX_MAX_VIEWS && in->nviews < TEX_MAX_VIEWS; i++) {
        if (strcmp(names[i], "capture") == 0) continue;
        tex_view *v = &in->views[in->nviews];
        const cJSON *a = cJSON_GetObjectItemCaseSensitive(ce, names[i]);
        if (!cJSON_IsArray(a) || cJSON_GetArraySize(a) != 3) {
            char path[4096];
            return rs_err_set(err, RS_ERR_INPUT, rs_work_path(cfg, "irradiance.json", path, sizeof path), 0,
                              "capture_exposure has no factors for [%s]: expected 3 numbers for every further "
                              "capture (rerun irradiance with the same captures)",
                              names[i]);
        }
        for (int ch = 0; ch < 3; ch++) {
            double f = cJSON_GetArrayItem(a, ch)->valuedouble;
            if (!(isfinite(f) && f > 0)) {
                char path[4096];
                return rs_err_set(err, RS_ERR_INPUT, rs_work_path(cfg, "irradiance.json", path, sizeof path), 0,
                                  "capture_exposure of [%s], channel %d, is %g: expected a finite factor > 0", names[i],
                                  ch, f);
            }
            v->scale[ch] = f;
        }
        v->name = names[i];
        if (rs_capture_load(cfg, names[i], &v->cap, err) != 0) return -1;
        in->nviews++;
    }
    return 0;
}

/* in->unobserved from albedo.ply's observed and irradiance.ply's gathered (in->alb, in->irr). */
static int read_unobserved(tex_inputs *in, const char *ap, const char *ip, rs_err *err)
{
    size_t nf = in->nf;
    double *g = malloc((nf + 1) * sizeof *g);
    in->unobserved = malloc((nf + 1) * sizeof *in->unobserved);
    int rc = -1;
    if (!g || !in->unobserved)
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    else if (rs_faceprop_get(in->alb, ap, "observed", nf, in->unobserved, err) == 0 &&
             rs_faceprop_get(in->irr, ip, "gathered", nf, g, err) == 0) {
        for (size_t f = 0; f < nf; f++) in->unobserved[f] = !(in->unobserved[f] > 0) && g[f] > 0;
        rc = 0;
    }
    free(g);
    return rc;
}

static int read_inputs(const rs_config *cfg, tex_inputs *in, rs_err *err)
{
    char ap[4096], ip[4096], path[4096];
    rs_work_path(cfg, "albedo.ply", ap, sizeof ap);
    rs_work_path(cfg, "irradiance.ply", ip, sizeof ip);
    if (!(in->mesh = rs_mesh_read(ap, &in->alb, err))) return -1;
    size_t nf = in->nf = in->mesh->nfaces;
    in->rho = malloc((3 * nf + 1) * sizeof(double));
    in->esky = malloc((3 * nf + 1) * sizeof(double));
    in->esun = malloc((3 * nf + 1) * sizeof(double));
    in->G = malloc((3 * nf + 1) * sizeof(double));
    in->estimable = malloc((nf + 1) * sizeof(double));
    if (!in->rho || !in->esky || !in->esun || !in->G || !in->estimable)
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
    if (rs_faceprop_get_rgb(in->alb, ap, "albedo", nf, in->rho, err) != 0 ||
        rs_faceprop_get_rgb(in->alb, ap, "irradiance_inter", nf, in->G, err) != 0 ||
        rs_faceprop_get(in->alb, ap, "estimable", nf, in->estimable, err) != 0)
        return -1;
    if (!(in->irr = rs_ply_read(ip, err))) return -1;
    if (rs_faceprop_get_rgb(in->irr, ip, "irradiance_sky", nf, in->esky, err) != 0 ||
        rs_faceprop_get_rgb(in->irr, ip, "irradiance_sun", nf, in->esun, err) != 0)
        return -1;
    const char *secs[2];
    if (rs_config_sections(cfg, "capture", secs, 2) > 1 && read_unobserved(in, ap, ip, err) != 0) return -1;
    rs_ply_free(in->irr);
    in->irr = NULL;
    tex_view *v0 = &in->views[0];
    in->nviews = 1;
    v0->name = "capture";
    v0->scale[0] = v0->scale[1] = v0->scale[2] = 1;
    if (rs_capture_load(cfg, "capture", &v0->cap, err) != 0) return -1;
    const char *idp = rs_work_path(cfg, "facet_id.exr", path, sizeof path);
    if (!(v0->ids = rs_image_read(idp, err))) return -1;
    if (v0->ids->width != v0->cap.pano->width || v0->ids->height != v0->cap.pano->height || v0->ids->channels != 1)
        return rs_err_set(err, RS_ERR_INPUT, idp, 0, "does not match the panorama's size (rerun observe)");
    cJSON *irr = read_irradiance_json(cfg);
    in->sun = read_sun_direction(irr);
    int rc = load_further_views(cfg, irr, in, err);
    if (rc == 0 && rs_v3_len(in->sun) > 0.5) rc = read_occluders(cfg, irr, in, err);
    cJSON_Delete(irr);
    if (rc != 0) return -1;
    const char *o = rs_ply_find_comment(in->alb, "rhoscan_origin");
    if (!o || sscanf(o, "%lf %lf %lf", &in->origin[0], &in->origin[1], &in->origin[2]) != 3)
        in->origin[0] = in->origin[1] = in->origin[2] = 0;
    /* the PLYs hold every property as doubles (about 0.5 GB at 10^6 facets): gone once read */
    rs_ply_free(in->alb);
    in->alb = NULL;
    return 0;
}

/* The default texel: the 10th percentile over observed facets of a panorama pixel's footprint
 * at the facet (distance x pixel angle): the finest sampling the model has, robust to a few
 * facets next to the camera. */
static double default_texel(const tex_inputs *in)
{
    size_t nf = in->nf, n = 0;
    float *v = malloc((nf + 1) * sizeof *v);
    if (!v) return 0.01;
    double pix = M_PI / in->views[0].cap.pano->height;
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, nrm;
        double a;
        rs_mesh_face(in->mesh, f, &c, &nrm, &a);
        if (in->estimable[f] > 0 && a > 0)
            v[n++] = (float)(rs_v3_len(rs_v3_sub(c, in->views[0].cap.pose.position)) * pix);
    }
    double t = n ? rs_select_kth(v, n, n / 10) : 0.01;
    free(v);
    return t > 1e-4 ? t : 1e-4;
}

/* Per-corner D (3 values per corner, 9 per face): the area-weighted mean over the chart's faces
 * meeting at the corner's vertex. */
typedef struct {
    uint64_t key; /* chart << 32 | vertex */
    uint32_t face;
    uint8_t corner;
} corner_rec;

static int corner_cmp(const void *a, const void *b)
{
    const corner_rec *x = a, *y = b;
    if (x->key != y->key) return x->key < y->key ? -1 : 1;
    return x->face != y->face ? (x->face < y->face ? -1 : 1) : (x->corner > y->corner) - (x->corner < y->corner);
}

static double *corner_irradiance(const tex_inputs *in, const rs_atlas *a)
{
    size_t nf = in->nf, nc = 3 * nf;
    corner_rec *r = malloc(nc * sizeof *r);
    double *out = malloc((9 * nf + 1) * sizeof *out);
    if (!r || !out) {
        free(r);
        free(out);
        return NULL;
    }
    for (size_t f = 0; f < nf; f++)
        for (int k = 0; k < 3; k++)
            r[3 * f + k] =
                (corner_rec){(uint64_t)a->face_chart[f] << 32 | in->mesh->tris[3 * f + k], (uint32_t)f, (uint8_t)k};
    qsort(r, nc, sizeof *r, corner_cmp);
    for (size_t i = 0; i < nc;) {
        size_t j = i;
        double acc[3] = {0, 0, 0}, w = 0;
        for (; j < nc && r[j].key == r[i].key; j++) {
            size_t f = r[j].face;
            rs_v3 c, n;
            double area;
            rs_mesh_face(in->mesh, f, &c, &n, &area);
            double d[3];
            int ok = 1;
            for (int ch = 0; ch < 3; ch++) {
                d[ch] = in->esky[3 * f + ch] - in->esun[3 * f + ch] + in->G[3 * f + ch];
                ok &= isfinite(d[ch]) && d[ch] >= 0;
            }
            if (!ok || !(area > 0)) continue;
            for (int ch = 0; ch < 3; ch++) acc[ch] += area * d[ch];
            w += area;
        }
        for (size_t q = i; q < j; q++)
            for (int ch = 0; ch < 3; ch++) out[9 * (size_t)r[q].face + 3 * r[q].corner + ch] = w > 0 ? acc[ch] / w : 0;
        i = j;
    }
    free(r);
    return out;
}

typedef struct {
    const tex_inputs *in;
    const rs_scene *scene;
    const rs_scene *sun_scene; /* scene, or with the irradiance stage's occluders attached: for the sun's rays */
    rs_tex_pages *t;
    double *Dc;  /* corner_irradiance */
    double *U;   /* 3 per chart: the sun's normal irradiance */
    float *vis;  /* per texel: V, -1 where the sun is behind the face (the pages' sigma until the albedo) */
    float *L;    /* 3 per texel: radiance, flag TEX_SEEN when measured (the pages' rgb until the albedo) */
    int sub_max; /* sub-samples per side, at most */
    int area;    /* [texture] filter = area: the texel's mean of the pixels read as constant squares */
    size_t view_seen[TEX_MAX_VIEWS]; /* texels each view saw */
    size_t multi_seen;               /* texels two views or more saw */
    size_t others_only;              /* texels only further captures saw */
} tex_ctx;

/* V at point p (normal n): SUN_RAYS rays toward points of the sun's disc. */
static float sun_visibility(const tex_ctx *c, rs_v3 p, rs_v3 n)
{
    rs_v3 s = c->in->sun;
    if (rs_v3_dot(s, n) <= 0) return -1;
    rs_v3 t1, t2;
    rs_v3_basis(s, &t1, &t2);
    rs_ray rays[SUN_RAYS];
    uint8_t occ[SUN_RAYS];
    double off = rs_scene_offset(c->scene, p) * 4;
    static const double jx[SUN_RAYS] = {0.5, -0.5, -0.5, 0.5}, jy[SUN_RAYS] = {0.5, 0.5, -0.5, -0.5};
    for (int r = 0; r < SUN_RAYS; r++) {
        rs_v3 d =
            rs_v3_add(s, rs_v3_add(rs_v3_scale(t1, jx[r] * SUN_RADIUS_RAD), rs_v3_scale(t2, jy[r] * SUN_RADIUS_RAD)));
        rays[r] = (rs_ray){rs_v3_add(p, rs_v3_scale(n, off)), rs_v3_norm(d), 0, INFINITY};
    }
    rs_scene_occluded(c->sun_scene, rays, occ, SUN_RAYS);
    int esc = 0;
    for (int r = 0; r < SUN_RAYS; r++) esc += !occ[r];
    return (float)esc / SUN_RAYS;
}

/* 1 when view v's four pixels around continuous coordinates (X, Y) all see chart ch and hold
 * usable radiance. */
static int pixels_on_chart(const tex_ctx *c, const tex_view *v, double X, double Y, uint32_t ch)
{
    const rs_image *ids = v->ids, *pano = v->cap.pano;
    int W = ids->width, H = ids->height, x0 = (int)floor(X - 0.5), y0 = (int)floor(Y - 0.5);
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 2; i++) {
            int x = ((x0 + i) % W + W) % W, y = y0 + j < 0 ? 0 : (y0 + j >= H ? H - 1 : y0 + j);
            float id = ids->data[(size_t)y * W + x];
            if (!(id >= 0 && id < (float)c->in->nf)) return 0;
            if (c->t->atlas->face_chart[(size_t)id] != ch) return 0;
            if (!rs_capture_pixel_ok(rs_image_px(pano, x, y))) return 0;
        }
    return 1;
}

/* [texture] filter = area: the pixel holding continuous coordinates (X, Y), the panorama read as
 * constant squares (nearest), of view v into px; 0 when that pixel does not see chart ch or is not usable. */
static int pixel_on_chart(const tex_ctx *c, const tex_view *v, double X, double Y, uint32_t ch, float px[3])
{
    const rs_image *ids = v->ids, *pano = v->cap.pano;
    int W = ids->width, H = ids->height, x = ((int)floor(X) % W + W) % W, y = (int)floor(Y);
    y = y < 0 ? 0 : (y >= H ? H - 1 : y);
    float id = ids->data[(size_t)y * W + x];
    if (!(id >= 0 && id < (float)c->in->nf) || c->t->atlas->face_chart[(size_t)id] != ch) return 0;
    const float *q = rs_image_px(pano, x, y);
    if (!rs_capture_pixel_ok(q)) return 0;
    for (int k = 0; k < 3; k++) px[k] = q[k];
    return 1;
}

/* Sub-samples per texel side: bilinear, n = texel / footprint (1 to sub_max), each lookup already
 * spreading over a pixel; area, two per footprint (2 to 2 sub_max), so that the nearest-pixel
 * lookups weigh each pixel by about its share of the texel. */
static int texel_subsamples(const tex_ctx *c, double foot)
{
    double r = c->t->atlas->texel / foot;
    int ns = c->area ? (int)ceil(2 * r) : (int)ceil(r), lo = c->area ? 2 : 1,
        hi = c->area ? 2 * c->sub_max : c->sub_max;
    return ns < lo ? lo : (ns > hi ? hi : ns);
}

/* L of view v at texel (x, y) of face f, point p: the mean of the sub-samples that the view
 * sees on the texel's own chart, unscaled. Returns 1 when any was, with the view's weight in w:
 * cos(view) x min(1, texel area / the pixel's footprint on the surface), the footprint
 * (distance x pixel angle)^2 / cos: a direct, near, fine view counts more than a grazing, far,
 * coarse one, and views that resolve the texel count alike but for their angle. */
static int view_radiance(const tex_ctx *c, const tex_view *v, uint32_t f, rs_v3 p, float L[3], double *w)
{
    const rs_capture *cap = &v->cap;
    rs_v3 n = rs_scene_normal(c->scene, f);
    rs_v3 d = rs_v3_sub(p, cap->pose.position);
    double dist = rs_v3_len(d), cosv = -rs_v3_dot(n, d) / dist;
    if (!(cosv > 0.02)) return 0;
    double pix = M_PI / cap->pano->height;
    int ns = texel_subsamples(c, dist * pix / fmax(cosv, 0.2));
    rs_ray ray = {cap->pose.position, d, 0, 1 - 4 * rs_scene_offset(c->scene, p) / dist};
    uint8_t occ;
    rs_scene_occluded(c->scene, &ray, &occ, 1);
    if (occ) return 0;
    const rs_atlas_chart *ch = &c->t->atlas->charts[c->t->atlas->face_chart[f]];
    double acc[3] = {0, 0, 0};
    int used = 0;
    double tx = c->t->atlas->texel;
    for (int j = 0; j < ns; j++)
        for (int i = 0; i < ns; i++) {
            double ds = ((i + 0.5) / ns - 0.5) * tx, dt = ((j + 0.5) / ns - 0.5) * tx;
            rs_v3 q = rs_v3_add(p, rs_v3_add(rs_v3_scale(ch->eu, ds), rs_v3_scale(ch->ev, -dt)));
            double u, vv;
            rs_pano_dir_to_uv(rs_pose_dir_to_local(&cap->pose, rs_v3_sub(q, cap->pose.position)), &u, &vv);
            double X = u * cap->pano->width, Y = vv * cap->pano->height;
            uint32_t chart = c->t->atlas->face_chart[f];
            float px[3];
            if (c->area) {
                if (!pixel_on_chart(c, v, X, Y, chart, px)) continue;
            } else {
                if (!pixels_on_chart(c, v, X, Y, chart)) continue;
                rs_pano_sample(cap->pano, u, vv, px);
            }
            for (int k = 0; k < 3; k++) acc[k] += px[k];
            used++;
        }
    if (!used) return 0;
    for (int k = 0; k < 3; k++) L[k] = (float)(acc[k] / used);
    double area = (dist * pix) * (dist * pix) / cosv;
    *w = cosv * fmin(1.0, tx * tx / area);
    return 1;
}

/* L at texel (x, y) of face f: every view that sees it (view_radiance), each brought to
 * [capture]'s exposure, blended by the views' weights. One view's L is taken as it is. seen:
 * per view, 1 when it saw the texel. Returns the views that saw it. */
static int texel_radiance(const tex_ctx *c, uint32_t f, int x, int y, float L[3], uint8_t *seen)
{
    double b[3];
    rs_v3 p = rs_tex_point(c->t, f, x, y, b);
    double acc[3] = {0, 0, 0}, wsum = 0;
    int nseen = 0;
    float one[3] = {0, 0, 0};
    for (int vi = 0; vi < c->in->nviews; vi++) {
        const tex_view *v = &c->in->views[vi];
        float Lv[3];
        double w = 0;
        seen[vi] = (uint8_t)view_radiance(c, v, f, p, Lv, &w);
        if (!seen[vi]) continue;
        for (int k = 0; k < 3; k++) {
            one[k] = vi == 0 ? Lv[k] : (float)(v->scale[k] * Lv[k]);
            acc[k] += w * one[k];
        }
        wsum += w;
        nseen++;
    }
    if (!nseen) return 0;
    for (int k = 0; k < 3; k++) L[k] = nseen == 1 || !(wsum > 0) ? one[k] : (float)(acc[k] / wsum);
    return nseen;
}

/* Texel rows per block of the work queue: a row's cost runs from nothing (no surface) to
 * several views' rays per texel, so blocks are small against a rank's share. */
#define TEX_ROW_BLOCK 4

/* The texels of row `row` (of the pages' npages x side): L and V, and what each view saw. */
static void measure_row(tex_ctx *c, long row, size_t *by, size_t *multi, size_t *others)
{
    rs_tex_pages *t = c->t;
    int S = t->side, nv = c->in->nviews, has_sun = rs_v3_len(c->in->sun) > 0.5;
    uint8_t seen[TEX_MAX_VIEWS];
    for (int x = 0; x < S; x++) {
        size_t k = (size_t)row * S + (size_t)x;
        if (t->face[k] < 0) continue;
        uint32_t f = (uint32_t)t->face[k];
        int y = (int)(row % S);
        int ns = texel_radiance(c, f, x, y, c->L + 3 * k, seen);
        if (ns) {
            t->flags[k] |= TEX_SEEN;
            if (ns > seen[0]) t->flags[k] |= TEX_FURTHER;
            for (int v = 0; v < nv; v++) by[v] += seen[v];
            *multi += ns > 1;
            *others += !seen[0];
        }
        if (has_sun) {
            double b[3];
            c->vis[k] = sun_visibility(c, rs_tex_point(t, f, x, y, b), rs_scene_normal(c->scene, f));
        }
    }
}

/* First pass over the texels: L and V, and what each view saw. The rows go in blocks to
 * whichever thread of whichever MPI rank asks first (common/par.h), and the ranks then exchange
 * them (rs_tex_share): each texel's figures depend on the texel alone, so every rank ends with
 * the single process's bytes. Collective. */
static int pass_measure(tex_ctx *c, rs_err *err)
{
    rs_tex_pages *t = c->t;
    int nv = c->in->nviews;
    size_t rows = (size_t)t->npages * (size_t)t->side;
    for (size_t k = 0; k < t->ntex; k++) c->vis[k] = -1; /* also off the surface: the flags file's sigma */
    int ranks = rs_par_size() > 1;
    uint8_t *mine = ranks ? calloc(rows ? rows : 1, 1) : NULL;
    rs_par_queue *queue = rs_par_queue_new(rows, TEX_ROW_BLOCK);
    if (rs_par_any(!queue || (ranks && !mine))) {
        rs_par_queue_free(queue);
        free(mine);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the texels' work queue");
    }
#pragma omp parallel
    {
        size_t by[TEX_MAX_VIEWS] = {0}, multi = 0, others = 0, begin, end;
        while (rs_par_queue_take(queue, &begin, &end))
            for (size_t row = begin; row < end; row++) {
                measure_row(c, (long)row, by, &multi, &others);
                if (mine) mine[row] = 1;
            }
#pragma omp critical(tex_measure_counts)
        {
            for (int v = 0; v < nv; v++) c->view_seen[v] += by[v];
            c->multi_seen += multi;
            c->others_only += others;
        }
    }
    rs_par_queue_free(queue);
    rs_tex_measured m = {.L = c->L, .vis = c->vis, .flag_mask = TEX_SEEN | TEX_FURTHER, .ncounts = nv + 2};
    for (int v = 0; v < nv; v++) m.counts[v] = c->view_seen[v];
    m.counts[nv] = c->multi_seen;
    m.counts[nv + 1] = c->others_only;
    int rc = rs_tex_share(t, &m, mine, err);
    free(mine);
    if (rc != 0) return -1;
    for (int v = 0; v < nv; v++) c->view_seen[v] = (size_t)m.counts[v];
    c->multi_seen = (size_t)m.counts[nv];
    c->others_only = (size_t)m.counts[nv + 1];
    return 0;
}

/* U per chart from the facets' sun term and their mean texel V. */
static int chart_sun(tex_ctx *c)
{
    const rs_atlas *a = c->t->atlas;
    size_t nf = c->in->nf;
    double *vs = calloc(2 * nf + 1, sizeof *vs), *num = calloc(3 * a->ncharts + 1, sizeof *num),
           *den = calloc(a->ncharts + 1, sizeof *den);
    if (!vs || !num || !den || !(c->U = calloc(3 * a->ncharts + 1, sizeof *c->U))) {
        free(vs);
        free(num);
        free(den);
        return -1;
    }
    for (size_t k = 0; k < c->t->ntex; k++)
        if (c->t->face[k] >= 0 && c->vis[k] >= 0) {
            vs[2 * (size_t)c->t->face[k]] += c->vis[k];
            vs[2 * (size_t)c->t->face[k] + 1] += 1;
        }
    for (size_t f = 0; f < nf; f++) {
        if (!(vs[2 * f + 1] > 0)) continue;
        rs_v3 cen, n;
        double area;
        rs_mesh_face(c->in->mesh, f, &cen, &n, &area);
        double cs = rs_v3_dot(n, c->in->sun);
        size_t ch = a->face_chart[f];
        int ok = 1;
        for (int q = 0; q < 3; q++) ok &= isfinite(c->in->esun[3 * f + q]) && c->in->esun[3 * f + q] >= 0;
        if (!ok || !(cs > 0)) continue;
        for (int q = 0; q < 3; q++) num[3 * ch + q] += area * c->in->esun[3 * f + q];
        den[ch] += area * cs * vs[2 * f] / vs[2 * f + 1];
    }
    for (size_t ch = 0; ch < a->ncharts; ch++)
        for (int q = 0; q < 3; q++) c->U[3 * ch + q] = den[ch] > 0 ? num[3 * ch + q] / den[ch] : 0;
    free(vs);
    free(num);
    free(den);
    return 0;
}

typedef struct {
    size_t texels, seen, penumbra, unseen;
    int views;
    size_t view_seen[TEX_MAX_VIEWS], multi_seen, others_only;
} tex_counts;

/* Second pass: rho = pi L / E, or the facet's albedo. */
static void pass_albedo(tex_ctx *c, tex_counts *n)
{
    rs_tex_pages *t = c->t;
    const tex_inputs *in = c->in;
    int S = t->side;
    size_t texels = 0, seen = 0, pen = 0;
    long rows = (long)t->npages * S;
#pragma omp parallel for schedule(dynamic, 8) reduction(+ : texels, seen, pen)
    for (long row = 0; row < rows; row++)
        for (int x = 0; x < S; x++) {
            size_t k = (size_t)row * S + (size_t)x;
            if (t->face[k] < 0) continue;
            uint32_t f = (uint32_t)t->face[k];
            size_t ch = t->atlas->face_chart[f];
            double b[3];
            rs_tex_point(t, f, x, (int)(row % S), b);
            double cs = rs_v3_dot(rs_scene_normal(c->scene, f), in->sun), E[3], Esun = 0, Etot = 0;
            for (int q = 0; q < 3; q++) {
                E[q] = 0;
                for (int v = 0; v < 3; v++) E[q] += b[v] * c->Dc[9 * (size_t)f + 3 * v + q];
                double s = c->vis[k] > 0 && cs > 0 ? c->U[3 * ch + q] * cs * c->vis[k] : 0;
                E[q] += s;
                Esun += (c->vis[k] >= 0 && cs > 0 ? c->U[3 * ch + q] * cs : 0) / 3;
                Etot += E[q] / 3;
            }
            texels++;
            /* a facet [capture] did not observe has no albedo of its own: a further capture's L
             * there stands on the facet's gathered light */
            int ok = (t->flags[k] & TEX_SEEN) &&
                (in->estimable[f] > 0 || (in->unobserved && in->unobserved[f] > 0 && (t->flags[k] & TEX_FURTHER)));
            t->flags[k] &= (uint8_t) ~(TEX_SEEN | TEX_FURTHER);
            for (int q = 0; q < 3; q++) ok &= E[q] > 0 && isfinite(E[q]);
            if (c->vis[k] > 0 && c->vis[k] < 1) {
                t->flags[k] |= RS_TEX_PENUMBRA;
                pen++;
            }
            if (!ok) {
                for (int q = 0; q < 3; q++) t->rgb[3 * k + q] = (float)in->rho[3 * f + q];
                t->flags[k] |= RS_TEX_UNSEEN;
                t->sigma[k] = 0;
                continue;
            }
            seen++;
            for (int q = 0; q < 3; q++) t->rgb[3 * k + q] = (float)(M_PI * c->L[3 * k + q] / E[q]);
            /* one shadow ray's worth of the sun, for a texel the edge crosses */
            t->sigma[k] = (t->flags[k] & RS_TEX_PENUMBRA) ? (float)(Esun / (2.0 * SUN_RAYS) / Etot) : 0;
        }
    n->texels = texels;
    n->seen = seen;
    n->penumbra = pen;
    n->unseen = texels - seen;
}

/* The texture's pages: albedo_texture.exr (R G B, linear) and .png (sRGB) from the pages' own
 * array, and albedo_texture_flags.exr (flags, sigma); albedo_texture_P.* with several pages.
 * names[p] gets each PNG's name. */
static int write_pages(const rs_config *cfg, const rs_tex_pages *t, char names[][64], rs_err *err)
{
    int S = t->side;
    rs_image *fl = rs_image_new(S, S, 2);
    if (!fl) return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for a %d x %d texture page", S, S);
    static const char *const rgbn[] = {"R", "G", "B"}, *const fln[] = {"flags", "sigma"};
    for (int p = 0; p < t->npages; p++) {
        size_t base = (size_t)p * S * S;
        rs_image page = {S, S, 3, t->rgb + 3 * base}; /* borrowed */
        for (size_t k = 0; k < (size_t)S * S; k++) {
            fl->data[2 * k] = t->flags[base + k];
            fl->data[2 * k + 1] = t->sigma[base + k];
        }
        char file[48];
        if (t->npages == 1)
            snprintf(file, sizeof file, "albedo_texture");
        else
            snprintf(file, sizeof file, "albedo_texture_%d", p);
        snprintf(names[p], 64, "%s.png", file);
        /* the three files on the threads there are: each writer is serial */
        rs_err werr[3] = {{0}};
        int wrc[3];
#pragma omp parallel for schedule(static, 1)
        for (int w = 0; w < 3; w++) {
            char wpath[4096], wname[80];
            snprintf(wname, sizeof wname, w == 0 ? "%s.exr" : w == 1 ? "%s_flags.exr" : "%s.png", file);
            rs_work_path(cfg, wname, wpath, sizeof wpath);
            wrc[w] = w == 0 ? rs_image_write_exr(&page, wpath, rgbn, 0, "rhoscan texture: albedo, linear", &werr[w])
                : w == 1    ? rs_image_write_exr(fl, wpath, fln, 0,
                                                 "rhoscan texture: flags 1 unseen (facet albedo), 2 penumbra, 4 edge, "
                                                    "8 gutter; sigma relative",
                                                 &werr[w])
                            : rs_image_write_png(&page, wpath, 1.0f, &werr[w]);
        }
        for (int w = 0; w < 3; w++)
            if (wrc[w] != 0) {
                if (err) *err = werr[w];
                rs_image_free(fl);
                return -1;
            }
    }
    rs_image_free(fl);
    return 0;
}

static void report_texture(rs_report *rep, const rs_atlas *a, const tex_counts *n, size_t vertices,
                           const char *const *names)
{
    rs_json_set_num(rep->metrics, "texel_size_m", a->texel);
    rs_json_set_int(rep->metrics, "charts", (long long)a->ncharts);
    rs_json_set_int(rep->metrics, "pages", a->npages);
    rs_json_set_int(rep->metrics, "page_side", a->side);
    rs_json_set_num(rep->metrics, "chart_rect_texels", a->rect_texels);
    rs_json_set_int(rep->metrics, "surface_texels", (long long)n->texels);
    rs_json_set_int(rep->metrics, "seen_texels", (long long)n->seen);
    rs_json_set_int(rep->metrics, "unseen_texels", (long long)n->unseen);
    rs_json_set_int(rep->metrics, "penumbra_texels", (long long)n->penumbra);
    rs_json_set_num(rep->metrics, "penumbra_share", n->texels ? (double)n->penumbra / n->texels : 0);
    rs_json_set_int(rep->metrics, "export_vertices", (long long)vertices);
    if (n->views > 1) { /* further captures: what each saw (one capture: the figures above say it) */
        rs_json *vs = rs_json_set_obj(rep->metrics, "captures_seen_texels");
        for (int v = 0; v < n->views; v++) rs_json_set_int(vs, names[v], (long long)n->view_seen[v]);
        rs_json_set_int(rep->metrics, "blended_texels", (long long)n->multi_seen);
        rs_json_set_int(rep->metrics, "further_only_texels", (long long)n->others_only);
        rs_json_set_num(rep->metrics, "unseen_share", n->texels ? (double)n->unseen / n->texels : 0);
    }
}

static int build_atlas(const rs_config *cfg, const tex_inputs *in, rs_atlas **out, rs_err *err)
{
    rs_atlas_opts ao = {0};
    ao.texel =
        rs_config_has(cfg, "texture", "texel_size") ? rs_config_real(cfg, "texture", "texel_size") : default_texel(in);
    ao.max_texels = (double)rs_config_int(cfg, "texture", "max_texels");
    ao.max_angle_deg = rs_config_real(cfg, "texture", "chart_angle_deg");
    ao.gutter = (int)rs_config_int(cfg, "texture", "gutter");
    int side = 64;
    while (side * 2 <= rs_config_int(cfg, "texture", "max_side")) side *= 2; /* a power of two */
    ao.max_side = side;
    *out = rs_atlas_build(in->mesh, &ao, err);
    return *out ? 0 : -1;
}

/* Collective: a further view's facet image, the facet each pixel's centre ray hits from the
 * front, -1 none (what the observe stage's facet_id.exr holds for [capture], traced the same
 * way). Under MPI each rank traces its band of rows (rs_par_range) and every rank ends with
 * the whole image: each rank's texels look into it. */
static int trace_ids(const rs_scene *scene, tex_view *v, rs_err *err)
{
    int w = v->cap.pano->width, h = v->cap.pano->height;
    size_t lo, hi;
    rs_par_range((size_t)h, &lo, &hi);
    int fail = !(v->ids = rs_image_new(w, h, 1));
#pragma omp parallel if (!fail)
    {
        rs_ray *rays = malloc((size_t)w * sizeof *rays);
        rs_hit *hits = malloc((size_t)w * sizeof *hits);
        if (!rays || !hits) {
#pragma omp atomic write
            fail = 1;
        }
#pragma omp for schedule(dynamic, 4)
        for (long r = (long)lo; r < (long)hi; r++) {
            if (!rays || !hits || !v->ids) continue;
            for (int x = 0; x < w; x++)
                rays[x] = (rs_ray){v->cap.pose.position,
                                   rs_pose_dir_to_world(&v->cap.pose, rs_pano_pixel_dir(w, h, x, (int)r)), 0, INFINITY};
            rs_scene_intersect_coherent(scene, rays, hits, (size_t)w);
            for (int x = 0; x < w; x++)
                v->ids->data[(size_t)r * w + x] =
                    hits[x].face == RS_NO_HIT || hits[x].backface ? -1.0f : (float)hits[x].face;
        }
        free(rays);
        free(hits);
    }
    if (rs_par_any(fail))
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory tracing [%s]'s facet image (on this or another "
                          "MPI rank)", v->name);
    return rs_par_allgather_range(v->ids->data, (size_t)h, (size_t)w * sizeof *v->ids->data, err);
}

/* Collective: rc, or -1 when any rank's was (err says so where rc was 0): no rank goes on into
 * the work queue or the exchange without the others. */
static int ranks_agree(int rc, rs_err *err)
{
    if (rs_par_any(rc != 0) && rc == 0)
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "texture: failed on another MPI rank (rank 0 says why)");
    return rc;
}

/* Collective: the texels measured on every rank (the costly part: a view ray and up to 3 x 3
 * lookups per view, and the sun's shadow rays, per texel); the rest on rank 0 alone. */
static int texture_compute(const rs_config *cfg, tex_inputs *in, rs_tex_pages *t, rs_report *rep, tex_counts *n,
                           rs_err *err)
{
    const char *filter = rs_config_string(cfg, "texture", "filter");
    tex_ctx c = {.in = in, .t = t, .sub_max = 3, .area = filter && strcmp(filter, "area") == 0};
    double t0 = rs_now();
    rs_scene *scene = rs_scene_new(in->mesh, err), *sun_scene = NULL;
    int rc = scene ? 0 : -1;
    c.scene = c.sun_scene = scene;
    /* the occluders on a scene of their own: they close the shell for the light, not for the
     * cameras' view rays (a camera saw what it saw) */
    if (rc == 0 && in->occ) {
        if (!(sun_scene = rs_scene_new(in->mesh, err)) ||
            rs_scene_set_occluders(sun_scene, in->occ, in->occ_proxy, in->occ_near, err) != 0)
            rc = -1;
        c.sun_scene = sun_scene;
        if (rc == 0)
            rs_log_info("texture: the sun's shadow rays see the irradiance stage's %zu occluder faces",
                        in->occ->nfaces);
    }
    double t1 = rs_now();
    rc = ranks_agree(rc, err); /* trace_ids is collective */
    for (int v = 1; v < in->nviews && rc == 0; v++) rc = trace_ids(scene, &in->views[v], err);
    if (rc == 0 && in->nviews > 1) rs_report_time(rep, "trace_views", rs_now() - t1);
    c.Dc = rc == 0 ? corner_irradiance(in, t->atlas) : NULL;
    c.vis = t->sigma;
    c.L = t->rgb;
    if (rc == 0 && !c.Dc) rc = rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %zu texels", t->ntex);
    if (rc == 0) rs_tex_raster(t);
    if ((rc = ranks_agree(rc, err)) != 0) goto out;
    rs_report_time(rep, "raster", rs_now() - t0);
    t0 = rs_now();
    rc = -1;
    if (pass_measure(&c, err) != 0) goto out;
    if (!rs_par_is_root()) { /* MPI: rank 0 has every texel; the albedo and the files are its */
        rc = 0;
        goto out;
    }
    if (chart_sun(&c) != 0) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory");
        goto out;
    }
    pass_albedo(&c, n);
    n->views = in->nviews;
    memcpy(n->view_seen, c.view_seen, sizeof n->view_seen);
    n->multi_seen = c.multi_seen;
    n->others_only = c.others_only;
    rs_report_time(rep, "texels", rs_now() - t0);
    t0 = rs_now();
    rs_tex_dilate(t);
    rs_report_time(rep, "dilate", rs_now() - t0);
    rc = 0;
out:
    free(c.Dc);
    free(c.U);
    rs_scene_free(sun_scene);
    rs_scene_free(scene);
    return rc;
}

int rs_texture_run(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    tex_inputs in = {0};
    rs_atlas *atlas = NULL;
    rs_tex_pages t = {0};
    tex_counts n = {0};
    int rc = -1;
    char(*names)[64] = NULL;
    double t0 = rs_now();
    if (read_inputs(cfg, &in, err) != 0 || build_atlas(cfg, &in, &atlas, err) != 0) goto failed;
    rs_report_time(rep, "atlas", rs_now() - t0);
    rs_log_info("texture: %zu charts, %d page(s) of %d x %d texels of %.4g m", atlas->ncharts, atlas->npages,
                atlas->side, atlas->side, atlas->texel);
    if (rs_tex_pages_alloc(&t, in.mesh, atlas) != 0 || !(names = calloc((size_t)atlas->npages, sizeof *names))) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for %d texture pages of %d x %d", atlas->npages,
                   atlas->side, atlas->side);
        goto failed;
    }
    if (rs_v3_len(in.sun) < 0.5) rs_report_skip(rep, "sun shadows per texel", "irradiance.json names no sun direction");
    if (texture_compute(cfg, &in, &t, rep, &n, err) != 0) goto out;
    if (!rs_par_is_root()) {
        rc = 0;
        goto out;
    }
    t0 = rs_now();
    if (write_pages(cfg, &t, names, err) != 0) goto out;
    const char *pn[1024];
    for (int p = 0; p < atlas->npages && p < 1024; p++) pn[p] = names[p];
    rs_tex_export e = {.cfg = cfg, .pages = &t, .png_names = pn};
    memcpy(e.origin, in.origin, sizeof e.origin);
    if (rs_tex_export_all(&e, err) != 0) goto out;
    rs_report_time(rep, "write", rs_now() - t0);
    const char *vnames[TEX_MAX_VIEWS];
    for (int v = 0; v < in.nviews; v++) vnames[v] = in.views[v].name;
    report_texture(rep, atlas, &n, e.vertices, vnames);
    rs_log_info("texture: %zu surface texels, %.1f %% seen, %.2f %% in a penumbra", n.texels,
                n.texels ? 100.0 * n.seen / n.texels : 0, n.texels ? 100.0 * n.penumbra / n.texels : 0);
    for (int v = 1; v < in.nviews; v++)
        rs_log_info("texture: [%s] saw %zu texels (exposure factor %.4g %.4g %.4g)", in.views[v].name, n.view_seen[v],
                    in.views[v].scale[0], in.views[v].scale[1], in.views[v].scale[2]);
    if (in.nviews > 1)
        rs_log_info("texture: %zu texels blended from two captures or more, %zu from further captures only",
                    n.multi_seen, n.others_only);
    rc = 0;
    goto out;
failed: /* before texture_compute's collective steps: the other ranks learn of it there */
    ranks_agree(-1, err);
out:
    free(names);
    rs_tex_pages_free(&t);
    rs_atlas_free(atlas);
    tex_inputs_free(&in);
    return rc;
}

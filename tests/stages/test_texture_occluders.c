/* The texture stage's sun shadows see the irradiance stage's occluders (issue 22, part 2's
 * second bullet; [irradiance] occluders). A wall of albedo 0.5 under a sky of E = 1 and a sun of
 * normal irradiance 3 at 45 degrees in front of it; a slab above the wall's left half that the
 * scan missed (its top never seen) is no facet of the mesh but an occluder face in
 * occluders.ply, as the irradiance stage closes such a slab. It shades x in [-4, 0], z in [1, 3]
 * of the wall, and the facets' sun (irradiance_sun) there is 0, as the irradiance stage found
 * it with its occluders. Checked per wall texel against the truth: in the slab's shadow and in
 * the sun, the median relative error is under 1 % (without the occluders on its shadow rays the
 * stage took the shade for sun, 60 % too dark, and spread the chart's sun power onto too many
 * texels); a texture stage whose irradiance.json counts other faces than occluders.ply holds
 * fails with bad input. */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "common/config.h"
#include "common/image.h"
#include "common/mesh.h"
#include "common/pano.h"
#include "common/ply.h"
#include "common/scene.h"
#include "common/select.h"
#include "meshing/atlas.h"
#include "stages/stages.h"
#include "tests/fixtures.h"
#include "tests/meshgen.h"

#define PANO_W     1024
#define WALL_FACES (2 * 32 * 16)
#define ALBEDO     0.5
#define SKY_E      1.0
#define SUN_E      3.0 /* normal irradiance */

static const double CAM[3] = {0.5, -1, 1.6};

/* toward the sun: 45 degrees up, from the wall's front (the wall faces -y) */
static rs_v3 sun_dir(void)
{
    return rs_v3_norm(rs_v3_make(0, -1, 1));
}

/* The slab's shadow on the wall (the plane y = 6): a point at height z reaches the slab's
 * underside z = 3 at y = 6 - (3 - z), inside it when that is >= 4, below it when z < 3. */
static int in_slab_shadow(rs_v3 p)
{
    return p.x < 0 && p.z > 1 && p.z < 3;
}

/* E at a wall point: sky and, outside the slab's shadow, the sun at 45 degrees. */
static double wall_irradiance(rs_v3 p)
{
    double cs = -sun_dir().y; /* the wall's normal is -y */
    return SKY_E + (in_slab_shadow(p) ? 0 : SUN_E * cs);
}

/* The camera's panorama (L = rho E / pi on the wall, a sky of 0.5 elsewhere) and facet image. */
static void render(const rs_scene *s, const char *path, const char *ids_path)
{
    int w = PANO_W, h = PANO_W / 2;
    rs_v3 c = rs_v3_make(CAM[0], CAM[1], CAM[2]);
    rs_image *img = rs_image_new(w, h, 3), *ids = rs_image_new(w, h, 1);
    for (int r = 0; r < h; r++)
        for (int x = 0; x < w; x++) {
            rs_ray ray = {c, rs_pano_pixel_dir(w, h, x, r), 0, INFINITY};
            rs_hit hit;
            rs_scene_intersect(s, &ray, &hit, 1);
            int face = hit.face != RS_NO_HIT && !hit.backface ? (int)hit.face : -1;
            double L = face >= 0 ? ALBEDO * wall_irradiance(rs_v3_add(c, rs_v3_scale(ray.dir, hit.t))) / M_PI : 0.5;
            for (int ch = 0; ch < 3; ch++) img->data[3 * ((size_t)r * w + x) + ch] = (float)L;
            ids->data[(size_t)r * w + x] = (float)face;
        }
    static const char *const rgb[] = {"R", "G", "B"}, *const y[] = {"Y"};
    rs_err err;
    if (rs_image_write_exr(img, path, rgb, 0, NULL, &err) != 0 || rs_image_write_exr(ids, ids_path, y, 0, NULL, &err))
        fail_msg("%s", err.msg);
    rs_image_free(img);
    rs_image_free(ids);
}

/* albedo.ply and irradiance.ply as the stages before would write them with the occluders: the
 * facets' sun 0 in the slab's shadow (every facet lies wholly in or out of it). */
static void write_facets(const rs_mesh *m, const char *work)
{
    size_t nf = m->nfaces;
    double *rho = malloc(nf * sizeof *rho), *zero = calloc(nf, sizeof *zero), *one = malloc(nf * sizeof *one),
           *sky = malloc(nf * sizeof *sky), *sun = malloc(nf * sizeof *sun);
    for (size_t f = 0; f < nf; f++) {
        rs_v3 c, n;
        double a;
        rs_mesh_face(m, f, &c, &n, &a);
        rho[f] = ALBEDO;
        one[f] = 1;
        sun[f] = wall_irradiance(c) - SKY_E;
        sky[f] = SKY_E + sun[f]; /* irradiance_sky includes the sun */
    }
    rs_err err;
    static const char ch[3] = {'r', 'g', 'b'};
    char name[64];
    rs_ply *alb = rs_ply_new(), *irr = rs_ply_new();
    rs_ply_element *fa = rs_mesh_to_ply(m, alb), *fi = rs_mesh_to_ply(m, irr);
    for (int k = 0; k < 3; k++) {
        snprintf(name, sizeof name, "albedo_%c", ch[k]);
        rs_ply_add_scalar(fa, name, RS_PLY_FLOAT32, rho);
        snprintf(name, sizeof name, "irradiance_inter_%c", ch[k]);
        rs_ply_add_scalar(fa, name, RS_PLY_FLOAT32, zero);
        snprintf(name, sizeof name, "irradiance_sky_%c", ch[k]);
        rs_ply_add_scalar(fi, name, RS_PLY_FLOAT32, sky);
        snprintf(name, sizeof name, "irradiance_sun_%c", ch[k]);
        rs_ply_add_scalar(fi, name, RS_PLY_FLOAT32, sun);
    }
    rs_ply_add_scalar(fa, "observed", RS_PLY_UINT8, one);
    rs_ply_add_scalar(fa, "estimable", RS_PLY_UINT8, one);
    rs_ply_add_scalar(fi, "gathered", RS_PLY_UINT8, one);
    if (rs_ply_write(alb, rs_test_path(work, "albedo.ply"), 1, &err) != 0 ||
        rs_ply_write(irr, rs_test_path(work, "irradiance.ply"), 1, &err) != 0)
        fail_msg("%s", err.msg);
    rs_ply_free(alb);
    rs_ply_free(irr);
    free(rho);
    free(zero);
    free(one);
    free(sky);
    free(sun);
}

/* occluders.ply: the slab's underside, x in [-4, 0], y in [4, 6], z = 3, facing down (toward the
 * known space the sun's rays come from), proxy facet 0. */
static void write_occluders(const char *work)
{
    rs_meshgen g = rs_meshgen_new(4, 2);
    rs_meshgen_rect(&g, rs_v3_make(-4, 4, 3), rs_v3_make(0, 2, 0), rs_v3_make(4, 0, 0), 1, 1);
    rs_mesh *occ = rs_meshgen_done(&g);
    rs_ply *ply = rs_ply_new();
    rs_ply_element *fe = rs_mesh_to_ply(occ, ply);
    double proxy[2] = {0, 0};
    rs_ply_add_scalar(fe, "proxy", RS_PLY_INT32, proxy);
    rs_err err;
    if (rs_ply_write(ply, rs_test_path(work, "occluders.ply"), 1, &err) != 0) fail_msg("%s", err.msg);
    rs_ply_free(ply);
    rs_mesh_free(occ);
}

typedef struct {
    size_t shade, sun;               /* wall texels measured in the slab's shadow, in the sun */
    double shade_median, sun_median; /* their median relative errors */
} wall_figures;

/* Runs the texture stage; fills the wall's figures (texels 2 cm or more from the wall's and the
 * shadow's edges). */
static int run_texture(const char *dir, const char *cfg_text, wall_figures *wf, rs_err *err)
{
    const char *ini = rs_test_path(dir, "scene.ini");
    rs_test_write(ini, cfg_text);
    rs_config *cfg = rs_config_load(ini, NULL, err);
    if (!cfg) fail_msg("%s", err->msg);
    rs_report rep;
    rs_fx_report_init(&rep);
    int rc = rs_texture_run(cfg, &rep, err);
    rs_fx_report_free(&rep);
    if (rc != 0 || !wf) {
        rs_config_free(cfg);
        return rc;
    }
    rs_atlas_opts ao = {.texel = rs_config_real(cfg, "texture", "texel_size"),
                        .max_texels = (double)rs_config_int(cfg, "texture", "max_texels"),
                        .max_angle_deg = rs_config_real(cfg, "texture", "chart_angle_deg"),
                        .gutter = (int)rs_config_int(cfg, "texture", "gutter")};
    int side = 64;
    while (side * 2 <= rs_config_int(cfg, "texture", "max_side")) side *= 2;
    ao.max_side = side;
    char work[4096];
    snprintf(work, sizeof work, "%s/work", dir);
    rs_mesh *m = rs_mesh_read(rs_test_path(work, "albedo.ply"), NULL, err);
    if (!m) fail_msg("%s", err->msg);
    rs_atlas *a = rs_atlas_build(m, &ao, err);
    rs_image *tex = a ? rs_image_read(rs_test_path(work, "albedo_texture.exr"), err) : NULL;
    if (!tex) fail_msg("%s", err->msg);
    const rs_atlas_chart *c = &a->charts[a->face_chart[0]]; /* the wall: one plane, one chart */
    assert_int_equal(c->count, WALL_FACES);
    float *e_shade = malloc((size_t)c->w * c->h * sizeof *e_shade),
          *e_sun = malloc((size_t)c->w * c->h * sizeof *e_sun);
    memset(wf, 0, sizeof *wf);
    for (int y = c->y0; y < c->y0 + c->h; y++)
        for (int x = c->x0; x < c->x0 + c->w; x++) {
            const float *v = tex->data + 3 * ((size_t)y * a->side + x);
            double st = c->smin + (x - c->x0) * a->texel, tt = c->tmax - (y - c->y0) * a->texel;
            rs_v3 p = rs_v3_add(c->origin, rs_v3_add(rs_v3_scale(c->eu, st), rs_v3_scale(c->ev, tt)));
            if (p.x < -3.98 || p.x > 3.98 || p.z < 0.02 || p.z > 3.98) continue;            /* off the wall */
            if (fabs(p.x) < 0.02 || fabs(p.z - 1) < 0.02 || fabs(p.z - 3) < 0.02) continue; /* the shadow's edge */
            double e = fabs(v[1] / ALBEDO - 1);
            if (in_slab_shadow(p))
                e_shade[wf->shade++] = (float)e;
            else
                e_sun[wf->sun++] = (float)e;
        }
    if (wf->shade) wf->shade_median = rs_select_kth(e_shade, wf->shade, wf->shade / 2);
    if (wf->sun) wf->sun_median = rs_select_kth(e_sun, wf->sun, wf->sun / 2);
    free(e_shade);
    free(e_sun);
    rs_image_free(tex);
    rs_atlas_free(a);
    rs_mesh_free(m);
    rs_config_free(cfg);
    return 0;
}

static void test_slab_occluder(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("texture_occluders");
    char work[4096], cfg[8192], cmd[8192];
    snprintf(work, sizeof work, "%s/work", dir);
    snprintf(cmd, sizeof cmd, "mkdir -p '%s'", work);
    assert_int_equal(system(cmd), 0);
    rs_meshgen g = rs_meshgen_new(33 * 17, WALL_FACES);
    rs_meshgen_rect(&g, rs_v3_make(-4, 6, 0), rs_v3_make(8, 0, 0), rs_v3_make(0, 0, 4), 32, 16);
    rs_mesh *m = rs_meshgen_done(&g);
    rs_scene *s = rs_fx_scene(m);
    render(s, rs_test_path(dir, "pano.exr"), rs_test_path(work, "facet_id.exr"));
    write_facets(m, work);
    write_occluders(work);
    rs_v3 sd = sun_dir();
    char json[1024];
    snprintf(json, sizeof json,
             "{\"sun_direction\": [%.17g, %.17g, %.17g], \"occluders\": {\"mode\": \"freespace\", \"faces\": 2, "
             "\"near_m\": 0.05}}\n",
             sd.x, sd.y, sd.z);
    rs_test_write(rs_test_path(work, "irradiance.json"), json);
    snprintf(cfg, sizeof cfg,
             "[pipeline]\nworkdir = %s\n[irradiance]\noccluders = freespace\n[texture]\ntexel_size = 0.04\n"
             "[capture]\npanorama = %s/pano.exr\nposition = 0.5 -1 1.6\n",
             work, dir);
    rs_err err;
    wall_figures wf;
    if (run_texture(dir, cfg, &wf, &err) != 0) fail_msg("%s", err.msg);
    print_message("slab's shadow: %zu texels, median error %.3f %%; sun: %zu texels, median error %.3f %%\n", wf.shade,
                  100 * wf.shade_median, wf.sun, 100 * wf.sun_median);
    assert_true(wf.shade > 4000); /* 4 m x 2 m of 4 cm texels, less the edges */
    assert_true(wf.sun > 8000);
    assert_true(wf.shade_median < 0.01);
    assert_true(wf.sun_median < 0.01);

    /* irradiance.json counting other faces than occluders.ply: an occluders.ply of another run */
    snprintf(json, sizeof json,
             "{\"sun_direction\": [%.17g, %.17g, %.17g], \"occluders\": {\"mode\": \"freespace\", \"faces\": 3, "
             "\"near_m\": 0.05}}\n",
             sd.x, sd.y, sd.z);
    rs_test_write(rs_test_path(work, "irradiance.json"), json);
    assert_int_not_equal(run_texture(dir, cfg, NULL, &err), 0);
    assert_int_equal(err.kind, RS_ERR_INPUT);
    assert_non_null(strstr(err.file, "occluders.ply"));
    rs_scene_free(s);
    rs_mesh_free(m);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_slab_occluder))

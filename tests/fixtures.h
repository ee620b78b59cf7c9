/* fixtures: the synthetic skies and scenes the tests build, so that each is written once:
 * panoramas in world axes from a radiance function, the sky maps made from them (every pixel
 * sky), the ray-tracing scene of a generated mesh, and the work folder an end-to-end run reads
 * (mesh.ply, pano.exr, scene.ini). Every helper fails the test when it cannot do its part. */
#ifndef RS_FIXTURES_H
#define RS_FIXTURES_H

#include <math.h>
#include <stddef.h>
#include "common/capture.h"
#include "common/image.h"
#include "common/mesh.h"
#include "common/scene.h"
#include "light/gather.h"
#include "pipeline/stage.h"
#include "sky/skyenv.h"
#include "tests/meshgen.h"

/* ---- skies ---- */

/* The solid angle of a 3-degree disc: the largest sun set the sky tests split off. */
#define RS_FX_SUN_MAX_SR (2 * M_PI * (1 - cos(3 * M_PI / 180)))

/* The radiance toward world direction d, seen at pixel k (row-major) of the panorama, into rgb. */
typedef void (*rs_fx_radiance)(rs_v3 d, size_t k, double rgb[3], void *ctx);

/* A w x h RGB panorama in world axes (identity pose) whose pixels hold (float) radiance(d) of
 * their centre's direction, row by row; all 0 when radiance is NULL. Caller frees. */
rs_image *rs_fx_pano(int w, int h, rs_fx_radiance radiance, void *ctx);
/* The same panorama as a capture with an identity pose (nothing else set). Caller releases. */
rs_capture rs_fx_capture(int w, int h, rs_fx_radiance radiance, void *ctx);
/* A uniform sky of radiance sky (every channel) with one pixel (sc, sr) of radiance sun. */
rs_capture rs_fx_sun_pixel_capture(int w, int h, float sky, float sun, int sc, int sr);

/* The sky map of cap with no model in view (every pixel sky): rs_skyenv_build with a sun
 * threshold of 50 x the median, sun sets up to max_sr, and explicit_sun. */
void rs_fx_sky_env(const rs_capture *cap, double max_sr, int explicit_sun, rs_skyenv *env);
/* What the sky tests build maps with: sun threshold 50, sun sets up to RS_FX_SUN_MAX_SR,
 * explicit sun, the given fill method and every other option 0. */
rs_skyenv_opts rs_fx_sky_opts(rs_skyfill_method method);
/* rs_skyenv_build_opts of cap with the model ids facet_id (< 0: sky). */
void rs_fx_sky_env_opts(const rs_capture *cap, const float *facet_id, const rs_skyenv_opts *o, rs_skyenv *env,
                        rs_skyenv_info *info);

/* A w x w/2 sky of random luminance (0.05 to 1.05 per pixel, grey; 0 at every dark_every-th
 * pixel when dark_every > 0) with a sun of 6 x 3 pixels of radiance sun about 45 degrees up,
 * and its sky map (sun sets up to 0.01 sr). */
void rs_fx_random_sky(int w, float sun, int dark_every, rs_capture *cap, rs_skyenv *env);

/* ---- scenes ---- */

/* The ray-tracing scene of m. */
rs_scene *rs_fx_scene(const rs_mesh *m);
/* A 1 x 1 m square at the origin (z = 0, facing +z), two triangles. */
rs_mesh *rs_fx_unit_square(void);
/* The gather most tests trace with: samples cosine and as many sky rays, sun_samples sun rays,
 * seed, and facets with the whole model below their plane skipped; every other setting 0. */
rs_gather_ctx rs_fx_gather_ctx(const rs_scene *scene, const rs_skyenv *env, int samples, int sun_samples,
                               uint32_t seed);
/* Releases what a gather test set up; any argument may be NULL. */
void rs_fx_release(rs_skyenv *env, rs_capture *cap, rs_scene *scene, rs_mesh *m);

/* ---- work folders of end-to-end runs ---- */

/* Writes img as dir/pano.exr (R, G, B; full float). */
void rs_fx_write_pano(const rs_image *img, const char *dir);
/* dir/mesh.ply: a 10 x 10 m floor (z = 0, centred on the origin, floor_cells x floor_cells) and
 * a 6 m high wall along y = 5 (wall_nu x wall_nv cells) whose normal faces -y, the camera's side. */
void rs_fx_write_floor_wall(const char *dir, int floor_cells, int wall_nu, int wall_nv);
/* dir/scene.ini for `rhoscan run`: work folder work, mesh.ply, one capture pano.exr at position
 * ("x y z"), [irradiance] samples = sky_samples = samples and sun_samples, then the lines of
 * extra (NULL: none) from line 12 on. Returns its path (a rs_test_path buffer). */
const char *rs_fx_write_scene_ini(const char *dir, const char *position, int samples, int sun_samples,
                                  const char *extra);

/* What a camera sees of a ground-and-wall scene (rs_meshgen_wall_ground), as radiance: sky(d)
 * above the horizon, far_ground below it beyond the model, wall on the wall. */
typedef struct {
    rs_meshgen_wall_ground scene;
    rs_v3 camera;
    double (*sky)(rs_v3 d, const void *ctx);
    const void *sky_ctx;
    double far_ground, wall;
} rs_fx_wall_ground_view;

/* Writes dir/pano.exr (w x w/2) of what view's camera sees; the model's ground holds
 * ground[3 f + ch] of the facet f that facet_id holds at the pixel, 0.2 where either is NULL or
 * the pixel holds no facet. */
void rs_fx_write_wall_ground_pano(const char *dir, int w, const rs_fx_wall_ground_view *view, const rs_image *facet_id,
                                  const double *ground);

/* ---- stage reports ---- */

/* A stage report with empty metrics, skips and timings, as the driver hands one to a stage. */
void rs_fx_report_init(rs_report *rep);
void rs_fx_report_free(rs_report *rep);

#endif

/* test_meshing: grid triangulation of synthetic scans (orientation, depth jumps, missing
 * returns, open sweeps, grazing angles) and the ingest and mesh stages end to end: on a
 * synthetic scan, on [mesh] input_mesh, and on the two_planes_sky reference scan. */
#include "tests/fixtures.h"
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "common/cloud.h"
#include "meshing/grid.h"
#include "common/image.h"
#include "common/mesh.h"
#include "stages/stages.h"

/* A scanner at o sweeping cols azimuths over az_span_deg (a full turn: no repeated column)
 * and rows elevations from -80 to -40 degrees, every ray hitting the plane z = 0 (steep enough
 * that neighbouring rows stay within the default 5 % range ratio). */
static rs_cloud *plane_scan(const double o[3], int cols, int rows, double az_span_deg)
{
    rs_cloud *c = calloc(1, sizeof *c);
    c->npoints = (size_t)cols * rows;
    c->xyz = malloc(3 * c->npoints * sizeof *c->xyz);
    c->valid = malloc(c->npoints);
    c->nscans = 1;
    c->scans = calloc(1, sizeof *c->scans);
    c->scans[0].cols = cols;
    c->scans[0].rows = rows;
    memcpy(c->scans[0].position, o, 3 * sizeof *o);
    int full = az_span_deg >= 360;
    for (int col = 0; col < cols; col++)
        for (int row = 0; row < rows; row++) {
            double az = az_span_deg * M_PI / 180 * col / (full ? cols : cols - 1);
            double el = (-80 + 40.0 * row / (rows - 1)) * M_PI / 180;
            double d[3] = {cos(el) * cos(az), cos(el) * sin(az), sin(el)};
            double t = -o[2] / d[2];
            size_t i = (size_t)col * rows + row;
            for (int j = 0; j < 3; j++) c->xyz[3 * i + j] = o[j] + t * d[j];
            c->valid[i] = 1;
        }
    return c;
}

static rs_grid_opts default_opts(void)
{
    rs_grid_opts o = {0.05, 85 * M_PI / 180, 2.5, 0, 0};
    return o;
}

/* Every face's normal points at the scanner (counter-clockwise seen from it). */
static void assert_faces_scanner(const rs_mesh *m, const double o[3])
{
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 c, n;
        rs_mesh_face(m, f, &c, &n, NULL);
        if (rs_v3_dot(n, rs_v3_sub(rs_v3_make(o[0], o[1], o[2]), c)) <= 0)
            fail_msg("face %zu faces away from the scanner", f);
    }
}

static void test_plane_orientation(void **state)
{
    (void)state;
    const double o[3] = {1, -2, 2};
    rs_cloud *c = plane_scan(o, 72, 20, 360);
    rs_grid_opts go = default_opts();
    rs_grid_stats st;
    rs_err err = {0};
    rs_mesh *m = rs_grid_triangulate(c, &go, &st, &err);
    if (!m) fail_msg("%s", err.msg);
    /* A full turn: the last column joins the first, 72 x 19 cells, two triangles each. */
    assert_int_equal(st.cells, 72 * 19);
    assert_int_equal(m->nfaces, 2 * 72 * 19);
    assert_int_equal(m->nverts, 72 * 20);
    assert_int_equal(st.dropped_depth + st.dropped_grazing + st.dropped_gap, 0);
    assert_faces_scanner(m, o);
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 n;
        rs_mesh_face(m, f, NULL, &n, NULL);
        assert_true(n.z > 1 - 1e-9); /* the floor's normal, up toward the scanner */
    }
    rs_mesh_free(m);

    /* One missing return: the four cells around it keep one triangle each. */
    c->valid[(size_t)10 * 20 + 7] = 0;
    m = rs_grid_triangulate(c, &go, &st, &err);
    assert_int_equal(m->nfaces, 2 * 72 * 19 - 4);
    assert_int_equal(m->nverts, 72 * 20 - 1);
    assert_faces_scanner(m, o);
    rs_mesh_free(m);
    rs_cloud_free(c);
}

/* A patch floating at half the range (z = 1 over the floor at z = 0): the cells between
 * patch and floor span a depth jump of 2:1 and must go; both sides stay meshed. */
static void test_depth_discontinuity(void **state)
{
    (void)state;
    const double o[3] = {0, 0, 2};
    rs_cloud *c = plane_scan(o, 72, 20, 360);
    for (int col = 10; col < 20; col++)
        for (int row = 5; row < 10; row++) {
            size_t i = (size_t)col * 20 + row;
            for (int j = 0; j < 3; j++) c->xyz[3 * i + j] = o[j] + 0.5 * (c->xyz[3 * i + j] - o[j]);
        }
    rs_grid_opts go = default_opts();
    rs_grid_stats st;
    rs_err err = {0};
    rs_mesh *m = rs_grid_triangulate(c, &go, &st, &err);
    assert_non_null(m);
    assert_true(st.dropped_depth > 0);
    size_t patch = 0, floor = 0;
    for (size_t f = 0; f < m->nfaces; f++) {
        double z[3];
        for (int j = 0; j < 3; j++) z[j] = m->verts[3 * (size_t)m->tris[3 * f + j] + 2];
        int on_patch = fabs(z[0] - 1) < 1e-5, same = fabs(z[0] - z[1]) < 1e-5 && fabs(z[0] - z[2]) < 1e-5;
        if (!same) fail_msg("face %zu joins the patch and the floor (z %g %g %g)", f, z[0], z[1], z[2]);
        patch += on_patch;
        floor += !on_patch;
    }
    assert_int_equal(patch, 2 * 9 * 4); /* the patch's inner 9 x 4 cells */
    /* The floor keeps two triangles per cell with no patch corner and one where a single
     * corner is on the patch (the other three make a triangle). */
    size_t want_floor = 0;
    for (int col = 0; col < 72; col++)
        for (int row = 0; row + 1 < 20; row++) {
            int on = 0;
            for (int dc = 0; dc < 2; dc++)
                for (int dr = 0; dr < 2; dr++) {
                    int cc = (col + dc) % 72, rr = row + dr;
                    on += cc >= 10 && cc < 20 && rr >= 5 && rr < 10;
                }
            want_floor += on == 0 ? 2 : on == 1 ? 1 : 0;
        }
    assert_int_equal(floor, want_floor);
    assert_faces_scanner(m, o);
    rs_mesh_free(m);
    rs_cloud_free(c);
}

/* A quarter sweep: the last column does not join the first (the angular gap drops that seam). */
static void test_open_sweep(void **state)
{
    (void)state;
    const double o[3] = {0, 0, 2};
    rs_cloud *c = plane_scan(o, 19, 20, 90);
    rs_grid_opts go = default_opts();
    rs_grid_stats st;
    rs_err err = {0};
    rs_mesh *m = rs_grid_triangulate(c, &go, &st, &err);
    assert_int_equal(st.dropped_gap, 19);
    assert_int_equal(m->nfaces, 2 * 18 * 19);
    rs_mesh_free(m);
    rs_cloud_free(c);
}

/* A tighter grazing limit: rows seen at more than 30 degrees from the floor's normal go. */
static void test_grazing(void **state)
{
    (void)state;
    const double o[3] = {0, 0, 2};
    rs_cloud *c = plane_scan(o, 36, 20, 360);
    rs_grid_opts go = default_opts();
    go.max_grazing_rad = 30 * M_PI / 180;
    rs_grid_stats st;
    rs_err err = {0};
    rs_mesh *m = rs_grid_triangulate(c, &go, &st, &err);
    assert_true(st.dropped_grazing > 0);
    for (size_t f = 0; f < m->nfaces; f++) {
        rs_v3 cen, n;
        rs_mesh_face(m, f, &cen, &n, NULL);
        rs_v3 ray = rs_v3_norm(rs_v3_sub(rs_v3_make(o[0], o[1], o[2]), cen));
        assert_true(rs_v3_dot(ray, n) >= cos(30 * M_PI / 180) - 1e-12);
    }
    assert_int_equal(st.dropped_depth, 0);
    assert_int_equal(m->nfaces + st.dropped_grazing, 2 * 36 * 19);
    rs_mesh_free(m);

    /* An unorganized cloud is refused. */
    c->nscans = 0;
    assert_null(rs_grid_triangulate(c, &go, &st, &err));
    c->nscans = 1;
    rs_cloud_free(c);
}

/* ---- the stages ---- */

typedef struct run {
    rs_report rep;
    rs_err err;
    int rc;
} run;

static rs_config *config(const char *dir, const char *text)
{
    rs_err err = {0};
    rs_config *cfg = rs_config_load_string(text, "test.ini", dir, NULL, &err);
    if (!cfg) fail_msg("config: %s", err.msg);
    return cfg;
}

/* A number from a report (the json module has no getter: look it up in the text). */
static double metric(const rs_report *rep, const char *key)
{
    char *text = rs_json_text(rep->metrics);
    const struct cJSON *at = rs_test_json_find(rs_test_json_text(text), key);
    double v = at ? rs_test_json_num(at, "") : NAN;
    free(text);
    return v;
}

/* A synthetic scan through ingest (as a PTX file) and mesh, with the facet size derived from
 * a 256 px wide panorama: 6 px * 2 pi / 256 * the median camera-vertex distance. */
static void test_stages_synthetic(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("meshing");
    const double o[3] = {0, 0, 2};
    rs_cloud *c = plane_scan(o, 90, 30, 360);
    /* As PTX: header with identity registration, points in scanner coordinates. */
    char *ptx = malloc(c->npoints * 80 + 1024);
    size_t len = (size_t)sprintf(ptx, "90\n30\n0 0 2\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 2 1\n");
    for (size_t i = 0; i < c->npoints; i++)
        len +=
            (size_t)sprintf(ptx + len, "%.9f %.9f %.9f 0.5\n", c->xyz[3 * i], c->xyz[3 * i + 1], c->xyz[3 * i + 2] - 2);
    rs_test_write(rs_test_path(dir, "scan.ptx"), ptx);
    free(ptx);

    rs_image *pano = rs_image_new(256, 128, 3);
    rs_err err = {0};
    assert_int_equal(
        rs_image_write_exr(pano, rs_test_path(dir, "pano.exr"), (const char *const[]){"R", "G", "B"}, 1, NULL, &err),
        0);
    rs_image_free(pano);
    rs_config *cfg = config(dir,
                            "[pipeline]\nworkdir = out\n[ingest]\nscan = scan.ptx\n"
                            "[capture]\npanorama = pano.exr\nposition = 3 0 1.5\n");
    rs_report rep;
    rs_fx_report_init(&rep);
    /* Mesh before ingest: cloud.ply is missing, and the message says what to do. */
    assert_int_equal(rs_mesh_run(cfg, &rep, &err), -1);
    assert_non_null(strstr(err.file, "cloud.ply"));
    assert_non_null(strstr(err.msg, "run the ingest stage first"));
    assert_int_equal(rs_ingest_run(cfg, &rep, &err), 0);
    assert_float_equal(metric(&rep, "points"), 90 * 30, 0);
    assert_float_equal(metric(&rep, "valid"), 90 * 30, 0);
    assert_float_equal(metric(&rep, "scans"), 1, 0);
    rs_fx_report_free(&rep);
    rs_fx_report_init(&rep);
    if (rs_mesh_run(cfg, &rep, &err) != 0) fail_msg("mesh: %s", err.msg);

    /* The facet size the stage chose, from the same triangulation done here. */
    rs_grid_opts go = default_opts();
    rs_mesh *grid = rs_grid_triangulate(c, &go, NULL, &err);
    double *dist = malloc(grid->nverts * sizeof *dist);
    for (size_t v = 0; v < grid->nverts; v++)
        dist[v] = rs_v3_len(rs_v3_sub(rs_mesh_vert(grid, (uint32_t)v), rs_v3_make(3, 0, 1.5)));
    for (size_t i = 1; i < grid->nverts; i++) /* insertion sort: small */
        for (size_t j = i; j > 0 && dist[j - 1] > dist[j]; j--) {
            double t = dist[j];
            dist[j] = dist[j - 1];
            dist[j - 1] = t;
        }
    size_t n = grid->nverts;
    double med = n % 2 ? dist[n / 2] : 0.5 * (dist[n / 2 - 1] + dist[n / 2]);
    double want = 6 * (2 * M_PI / 256) * med;
    free(dist);
    assert_float_equal(metric(&rep, "facet_size_m"), want, 1e-6 * want);
    /* The grid's triangles plus the cap that closes the hole below the scanner. */
    assert_float_equal(metric(&rep, "faces_in"), (double)grid->nfaces + metric(&rep, "nadir_triangles"), 0);
    rs_mesh_free(grid);

    char path[4096];
    rs_ply *ply = NULL;
    rs_mesh *m = rs_mesh_read(rs_work_path(cfg, "mesh.ply", path, sizeof path), &ply, &err);
    if (!m) fail_msg("%s", err.msg);
    assert_float_equal(strtod(rs_ply_find_comment(ply, "rhoscan_facet_size"), NULL), want, 1e-6 * want);
    assert_string_equal(rs_ply_find_comment(ply, "rhoscan_facet_size_source"), "panorama");
    assert_faces_scanner(m, o);
    assert_float_equal(metric(&rep, "faces"), (double)m->nfaces, 0);
    /* Facets span about pixels_per_facet pixels wherever they are: every edge at most that
     * many pixels' width at its distance from the camera (slack for the distance being taken
     * at the collapsed vertex), and simplification did reach that size on average. */
    double k = metric(&rep, "edge_per_metre_of_distance");
    assert_float_equal(k, 6 * (2 * M_PI / 256), 1e-12);
    double edge_sum = 0, ratio_max = 0;
    for (size_t f = 0; f < m->nfaces; f++)
        for (int j = 0; j < 3; j++) {
            rs_v3 a = rs_mesh_vert(m, m->tris[3 * f + j]), b = rs_mesh_vert(m, m->tris[3 * f + (j + 1) % 3]);
            double len = rs_v3_len(rs_v3_sub(b, a));
            rs_v3 mid = rs_v3_scale(rs_v3_add(a, b), 0.5);
            double d = rs_v3_len(rs_v3_sub(mid, rs_v3_make(3, 0, 1.5)));
            ratio_max = fmax(ratio_max, len / (k * d));
            edge_sum += len;
        }
    print_message("longest edge / (k distance) = %.3f\n", ratio_max);
    assert_true(ratio_max < 1.5);
    double me = metric(&rep, "mean_edge_m");
    assert_float_equal(me, edge_sum / (3.0 * m->nfaces), 0.2 * me); /* shared edges counted once there */
    assert_true(me >= 0.5 * want);
    rs_ply_free(ply);
    rs_mesh_free(m);
    rs_fx_report_free(&rep);
    rs_config_free(cfg);

    /* Without facet_size and without a panorama: a clear error. */
    cfg = config(dir, "[pipeline]\nworkdir = out\n[ingest]\nscan = scan.ptx\n");
    rs_fx_report_init(&rep);
    assert_int_equal(rs_mesh_run(cfg, &rep, &err), -1);
    assert_non_null(strstr(err.msg, "[mesh] facet_size is not set"));
    rs_fx_report_free(&rep);
    rs_config_free(cfg);
    rs_cloud_free(c);
    rs_test_rmtree(dir);
}

/* [mesh] input_mesh: ingest steps aside, mesh drops the zero-area face and the unused vertex. */
static void test_input_mesh(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("meshing");
    rs_test_write(rs_test_path(dir, "in.ply"),
                  "ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\nproperty float y\nproperty float z\n"
                  "element face 3\nproperty list uchar int vertex_indices\nend_header\n"
                  "0 0 0\n1 0 0\n1 1 0\n2 2 0\n9 9 9\n3 0 1 2\n3 0 2 3\n3 1 1 2\n");
    rs_config *cfg = config(dir, "[pipeline]\nworkdir = out\n[mesh]\ninput_mesh = in.ply\n");
    rs_report rep;
    rs_fx_report_init(&rep);
    rs_err err = {0};
    assert_int_equal(rs_ingest_run(cfg, &rep, &err), 0);
    char *skipped = rs_json_text(rep.skipped);
    assert_non_null(strstr(skipped, "[mesh] input_mesh given"));
    free(skipped);
    rs_fx_report_free(&rep);
    rs_fx_report_init(&rep);
    if (rs_mesh_run(cfg, &rep, &err) != 0) fail_msg("%s", err.msg);
    assert_float_equal(metric(&rep, "dropped_zero_area"), 2, 0); /* collinear 0 2 3 and repeated 1 1 2 */
    assert_float_equal(metric(&rep, "dropped_unused_vertices"), 2, 0);
    char path[4096];
    rs_mesh *m = rs_mesh_read(rs_work_path(cfg, "mesh.ply", path, sizeof path), NULL, &err);
    assert_non_null(m);
    assert_int_equal(m->nfaces, 1);
    assert_int_equal(m->nverts, 3);
    rs_mesh_free(m);
    rs_fx_report_free(&rep);
    rs_config_free(cfg);

    /* A mesh with an index out of range: the message names the file and the face. */
    rs_test_write(rs_test_path(dir, "in.ply"),
                  "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                  "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n1 1 0\n3 0 1 7\n");
    cfg = config(dir, "[pipeline]\nworkdir = out\n[mesh]\ninput_mesh = in.ply\n");
    rs_fx_report_init(&rep);
    assert_int_equal(rs_mesh_run(cfg, &rep, &err), -1);
    assert_non_null(strstr(err.file, "in.ply"));
    assert_non_null(strstr(err.msg, "face 0: vertex index 7"));
    rs_fx_report_free(&rep);
    rs_config_free(cfg);
    rs_test_rmtree(dir);
}

/* The programs: an unorganized PLY cloud ingests fine; without [ingest] scanner_position the
 * mesh stage cannot orient its surface and says so (exit 1). */
static void test_programs_unorganized(void **state)
{
    (void)state;
    char ingest[2048], mesh[2048];
    snprintf(ingest, sizeof ingest, "%s/rhoscan-ingest", rs_test_bin_dir());
    snprintf(mesh, sizeof mesh, "%s/rhoscan-mesh", rs_test_bin_dir());
    struct stat st;
    if (stat(ingest, &st) != 0 || stat(mesh, &st) != 0) skip();
    const char *dir = rs_test_tmpdir("meshing");
    rs_test_write(rs_test_path(dir, "pts.ply"),
                  "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                  "end_header\n0 0 0\n1 0 0\n0 1 0\n");
    rs_test_write(rs_test_path(dir, "c.ini"),
                  "[pipeline]\nworkdir = out\n[ingest]\nscan = pts.ply\n[mesh]\nfacet_size = 0.5\n");
    char cmd[8192], *out = NULL;
    snprintf(cmd, sizeof cmd, "'%s' '%s/c.ini'", ingest, dir);
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) fail_msg("ingest exit %d: %s", rc, out);
    free(out);
    snprintf(cmd, sizeof cmd, "'%s' '%s/c.ini'", mesh, dir);
    rc = rs_test_run(cmd, &out);
    assert_int_equal(rc, 1);
    if (!strstr(out, "[ingest] scanner_position") || !strstr(out, "cloud.ply")) fail_msg("unexpected message: %s", out);
    free(out);
    rs_test_rmtree(dir);
}

/* The two_planes_sky reference scan with facet_size 0.3: every vertex within 2 cm of the
 * truth (floor slab z in [-0.1, 0], wall slab y in [5, 5.1]) away from the slabs' edges. */
static double slab_distance(const double lo[3], const double hi[3], rs_v3 p, int *near_edge)
{
    double q[3] = {p.x, p.y, p.z}, out2 = 0, in = 1e300;
    int inside = 1, near = 0;
    for (int j = 0; j < 3; j++) {
        double d = q[j] < lo[j] ? lo[j] - q[j] : q[j] > hi[j] ? q[j] - hi[j] : 0;
        if (d > 0) inside = 0;
        out2 += d * d;
        double m = fmin(fabs(q[j] - lo[j]), fabs(q[j] - hi[j]));
        in = fmin(in, m);
        near += m < 0.3;
    }
    double dist = inside ? in : sqrt(out2);
    *near_edge = dist < 0.3 && near >= 2;
    return dist;
}

static void test_two_planes_reference(void **state)
{
    (void)state;
    const char *scan = rs_test_shared_file("reference/two_planes_sky/scan.ptx");
    if (!scan) skip();
    const char *dir = rs_test_tmpdir("meshing");
    char text[2048];
    snprintf(text, sizeof text, "[pipeline]\nworkdir = out\n[ingest]\nscan = %s\n[mesh]\nfacet_size = 0.3\n", scan);
    rs_config *cfg = config(dir, text);
    rs_report rep;
    rs_fx_report_init(&rep);
    rs_err err = {0};
    if (rs_ingest_run(cfg, &rep, &err) != 0) fail_msg("ingest: %s", err.msg);
    rs_fx_report_free(&rep);
    rs_fx_report_init(&rep);
    if (rs_mesh_run(cfg, &rep, &err) != 0) fail_msg("mesh: %s", err.msg);
    char path[4096];
    rs_mesh *m = rs_mesh_read(rs_work_path(cfg, "mesh.ply", path, sizeof path), NULL, &err);
    assert_non_null(m);
    const double lo[2][3] = {{-5, -5, -0.1}, {-5, 5, 0}}, hi[2][3] = {{5, 5, 0}, {5, 5.1, 8}};
    double worst = 0, worst_all = 0;
    for (size_t v = 0; v < m->nverts; v++) {
        rs_v3 p = rs_mesh_vert(m, (uint32_t)v);
        int near0, near1;
        double d0 = slab_distance(lo[0], hi[0], p, &near0), d1 = slab_distance(lo[1], hi[1], p, &near1);
        double d = fmin(d0, d1);
        worst_all = fmax(worst_all, d);
        if (!((d0 <= d1 && near0) || (d1 < d0 && near1))) worst = fmax(worst, d);
    }
    print_message("two_planes_sky: %zu facets, %zu vertices, farthest %.4f m (%.4f m near edges), mean edge %.3f m\n",
                  m->nfaces, m->nverts, worst, worst_all, metric(&rep, "mean_edge_m"));
    assert_true(worst < 0.02);
    assert_true(worst_all < 0.05);
    /* About (100 + 80) m^2 of surface at sqrt(3)/4 * 0.3^2 m^2 per facet: some 4600. */
    assert_true(m->nfaces > 2500 && m->nfaces < 8000);
    double me = metric(&rep, "mean_edge_m");
    assert_true(me >= 0.3 * 0.99 && me <= 0.3 * 1.15);
    const double scanner[3] = {0.5, -9, 4.2};
    assert_faces_scanner(m, scanner);
    rs_mesh_free(m);
    rs_fx_report_free(&rep);
    rs_config_free(cfg);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_plane_orientation), cmocka_unit_test(test_depth_discontinuity),
             cmocka_unit_test(test_open_sweep), cmocka_unit_test(test_grazing), cmocka_unit_test(test_stages_synthetic),
             cmocka_unit_test(test_input_mesh), cmocka_unit_test(test_programs_unorganized),
             cmocka_unit_test(test_two_planes_reference))

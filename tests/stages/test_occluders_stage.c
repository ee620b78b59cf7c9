/* [irradiance] occluders end to end: occluders.ply is written, blocks light, and never reaches
 * the albedo, the exports or the camera's facet-id image; a malformed occluder file is refused
 * with the file and what was expected. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "common/faceprop.h"
#include "common/fileio.h"
#include "common/image.h"
#include "common/mesh.h"
#include "common/ply.h"
#include "meshing/closing.h"
#include "tests/fixtures.h"
#include "tests/testutil.h"

/* A floor and a wall (fixtures.h) under a panorama of 0.5, run with extra [irradiance] lines and,
 * when occ_text is not NULL, the file bad_occ.ply holding it. */
static const char *run_scene(const char *tag, const char *extra, const char *occ_text, int expect_rc, char **out)
{
    const char *dir = rs_test_tmpdir(tag);
    if (occ_text) rs_test_write(rs_test_path(dir, "bad_occ.ply"), occ_text);
    rs_fx_write_floor_wall(dir, 8, 8, 5);
    rs_image *img = rs_image_new(128, 64, 3);
    for (size_t k = 0; k < 3 * (size_t)128 * 64; k++) img->data[k] = 0.5f;
    rs_fx_write_pano(img, dir);
    rs_image_free(img);
    rs_fx_write_scene_ini(dir, "0 -4 1.5", 64, 16, extra);
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/rhoscan' run scene.ini", dir, rs_test_bin_dir());
    int rc = rs_test_run(cmd, out);
    if (rc != expect_rc) print_message("exit %d: %s\n", rc, *out);
    assert_int_equal(rc, expect_rc);
    return dir;
}

static size_t ply_count(const char *path, const char *element)
{
    rs_err err;
    rs_ply *ply = rs_ply_read(path, &err);
    if (!ply) fail_msg("%s: %s", path, err.msg);
    rs_ply_element *el = rs_ply_find_element(ply, element);
    size_t n = el ? el->count : 0;
    rs_ply_free(ply);
    return n;
}

static size_t count_lines(const char *path, const char *prefix)
{
    const char *text = rs_test_read_text(path);
    size_t n = 0, len = strlen(prefix);
    for (const char *p = text; p && *p;) {
        if (strncmp(p, prefix, len) == 0) n++;
        const char *nl = strchr(p, '\n');
        p = nl ? nl + 1 : NULL;
    }
    return n;
}

/* With and without occluders (extra: the [irradiance] lines that turn them on): the same facets
 * in albedo.ply and the exports, the same facet-id image; occluders.ply holds faces and proxies
 * of mesh.ply's facets, each with its source (1 free space, 2 to 4 the planar closing); with
 * planes, irradiance.json reports the floor's and the wall's regions. */
static void check_occluders_stay_out(const char *extra, int planes)
{
    char *out = NULL;
    char off_dir[2048], on_dir[2048];
    snprintf(off_dir, sizeof off_dir, "%s",
             run_scene(planes ? "occp_off" : "occ_off", "occluders = off\n", NULL, 0, &out));
    free(out);
    snprintf(on_dir, sizeof on_dir, "%s", run_scene(planes ? "occp_on" : "occ_on", extra, NULL, 0, &out));
    free(out);
    char a[4200], b[4200];
    snprintf(a, sizeof a, "%s/work/occluders.ply", on_dir);
    assert_int_equal(access(a, F_OK), 0);
    size_t nocc = ply_count(a, "face");
    assert_true(nocc > 0);
    rs_err err;
    rs_ply *ply = NULL;
    rs_mesh *occ = rs_mesh_read(a, &ply, &err);
    assert_non_null(occ);
    rs_ply_prop *proxy = rs_ply_find_prop(rs_ply_find_element(ply, "face"), "proxy");
    assert_non_null(proxy);
    double *src = malloc(occ->nfaces * sizeof *src);
    assert_int_equal(rs_faceprop_get(ply, a, "source", occ->nfaces, src, &err), 0);
    for (size_t f = 0; f < occ->nfaces; f++) assert_true(src[f] >= 1 && src[f] <= (planes ? RS_CLOSE_SLAB : 1));
    free(src);
    rs_mesh_free(occ);
    rs_ply_free(ply);
    snprintf(b, sizeof b, "%s/work/occluders.ply", off_dir);
    assert_int_not_equal(access(b, F_OK), 0);
    snprintf(a, sizeof a, "%s/work/irradiance.json", on_dir);
    assert_true(rs_test_json_number(a, "occluders/faces") == (double)nocc);
    if (planes) assert_true(rs_test_json_number(a, "occluders/planes/regions") >= 2);

    const char *same_count[][2] = {{"albedo.ply", "face"}, {"albedo_vertex.ply", "face"}, {"mesh.ply", "face"}};
    for (size_t k = 0; k < sizeof same_count / sizeof same_count[0]; k++) {
        snprintf(a, sizeof a, "%s/work/%s", off_dir, same_count[k][0]);
        snprintf(b, sizeof b, "%s/work/%s", on_dir, same_count[k][0]);
        assert_int_equal(ply_count(a, same_count[k][1]), ply_count(b, same_count[k][1]));
    }
    snprintf(a, sizeof a, "%s/work/albedo.obj", off_dir);
    snprintf(b, sizeof b, "%s/work/albedo.obj", on_dir);
    assert_int_equal(count_lines(a, "f "), count_lines(b, "f "));
    assert_int_equal(count_lines(a, "v "), count_lines(b, "v "));
    uint64_t ha, hb;
    snprintf(a, sizeof a, "%s/work/facet_id.exr", off_dir);
    snprintf(b, sizeof b, "%s/work/facet_id.exr", on_dir);
    assert_int_equal(rs_hash_file(a, &ha, &err), 0);
    assert_int_equal(rs_hash_file(b, &hb, &err), 0);
    assert_true(ha == hb);
    /* Back to off in the same folder: the stale occluders.ply goes. */
    snprintf(a, sizeof a, "%s/scene.ini", on_dir);
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/rhoscan' run scene.ini --set irradiance.occluders=off", on_dir,
             rs_test_bin_dir());
    assert_int_equal(rs_test_run(cmd, &out), 0);
    free(out);
    snprintf(a, sizeof a, "%s/work/occluders.ply", on_dir);
    assert_int_not_equal(access(a, F_OK), 0);
    rs_test_rmtree(off_dir);
    rs_test_rmtree(on_dir);
}

static void test_occluders_stay_out_of_outputs(void **state)
{
    (void)state;
    check_occluders_stay_out("occluders = freespace\noccluder_margin = 3\n", 0);
    check_occluders_stay_out("occluders = freespace+planes\noccluder_margin = 3\n", 1);
}

static void expect_refused(const char *occ_text, const char *const *needles)
{
    char *out = NULL;
    const char *dir = run_scene("occ_bad", "occluders = file\noccluders_file = bad_occ.ply\n", occ_text, 1, &out);
    for (; *needles; needles++) {
        if (!strstr(out, *needles)) print_message("missing in '%s': '%s'\n", out, *needles);
        assert_non_null(strstr(out, *needles));
    }
    free(out);
    rs_test_rmtree(dir);
}

/* Not a PLY, a face out of range, no proxy, a proxy beyond mesh.ply's facets: exit 1, the file
 * named, what was expected said. */
static void test_bad_occluder_file(void **state)
{
    (void)state;
    const char *garbage[] = {"bad_occ.ply", NULL};
    expect_refused("this is not a PLY file\n", garbage);
    const char *head = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                       "element face 1\nproperty list uchar int vertex_indices\n";
    char text[2048];
    snprintf(text, sizeof text, "%sproperty int proxy\nend_header\n0 0 1\n1 0 1\n0 1 1\n3 0 1 7 0\n", head);
    const char *range[] = {"bad_occ.ply", NULL};
    expect_refused(text, range);
    snprintf(text, sizeof text, "%send_header\n0 0 1\n1 0 1\n0 1 1\n3 0 1 2\n", head);
    const char *noproxy[] = {"bad_occ.ply", "proxy", NULL};
    expect_refused(text, noproxy);
    snprintf(text, sizeof text, "%sproperty int proxy\nend_header\n0 0 1\n1 0 1\n0 1 1\n3 0 1 2 100000\n", head);
    const char *beyond[] = {"bad_occ.ply", "face 0: proxy 100000", "expected a facet index of mesh.ply", NULL};
    expect_refused(text, beyond);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_occluders_stay_out_of_outputs), cmocka_unit_test(test_bad_occluder_file))

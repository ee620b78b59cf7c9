/* The programs' behaviour on bad input: a clear message naming the file, the line or key, and
 * what was expected, with a non-zero exit; and, for panorama pixels that are not finite, a
 * warning and finite results. */
#include <cjson/cJSON.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "common/faceprop.h"
#include "common/image.h"
#include "tests/fixtures.h"
#include "tests/meshgen.h"
#include "common/ply.h"
#include "common/par.h"
#include "pipeline/options.h"
#include "tests/testutil.h"

static const char *prog(const char *name)
{
    static char buf[4][1024];
    static int next;
    char *b = buf[next++ % 4];
    snprintf(b, sizeof buf[0], "%s/%s", rs_test_bin_dir(), name);
    return b;
}

/* Runs `rhoscan run CONFIG`, returns the exit status and the output in *out. */
static int run(const char *config, const char *extra, char **out)
{
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "'%s' run '%s' %s", prog("rhoscan"), config, extra ? extra : "");
    return rs_test_run(cmd, out);
}

static void expect_failure(const char *config, const char *const *needles)
{
    char *out = NULL;
    int rc = run(config, NULL, &out);
    print_message("exit %d: %s", rc, out);
    assert_int_not_equal(rc, 0);
    for (; *needles; needles++) {
        if (!strstr(out, *needles)) print_message("missing in the message: '%s'\n", *needles);
        assert_non_null(strstr(out, *needles));
    }
    free(out);
}

/* A wall and a floor as a mesh file, and a panorama of a uniform radiance. */
static void write_scene(const char *dir, int pano_w, int pano_h, int nan_pixels)
{
    rs_fx_write_floor_wall(dir, 8, 8, 5);
    rs_image *img = rs_image_new(pano_w, pano_h, 3);
    for (size_t k = 0; k < 3 * (size_t)pano_w * pano_h; k++) img->data[k] = 0.5f;
    for (int k = 0; k < nan_pixels; k++) img->data[3 * ((size_t)k * 7919 % ((size_t)pano_w * pano_h))] = NAN;
    rs_fx_write_pano(img, dir);
    rs_image_free(img);
}

static const char *write_config(const char *dir, const char *extra)
{
    return rs_fx_write_scene_ini(dir, "0 -4 1.5", 64, 16, extra);
}

/* A build without MPI started by mpirun as one of several ranks (the launcher's environment
 * says so) refuses before it writes anything: every rank would write the same files. */
static void test_mpi_launch_without_mpi(void **state)
{
    (void)state;
    if (rs_par_built_with_mpi()) skip(); /* there MPI would start: tests/mpi covers it */
    const char *dir = rs_test_tmpdir("cli_mpi");
    write_scene(dir, 64, 32, 0);
    const char *cfg = write_config(dir, "");
    char cmd[4096], *out = NULL, work[4200];
    snprintf(cmd, sizeof cmd, "OMPI_COMM_WORLD_SIZE=3 '%s' run '%s'", prog("rhoscan"), cfg);
    int rc = rs_test_run(cmd, &out);
    print_message("exit %d: %s", rc, out);
    assert_int_equal(rc, 1);
    assert_non_null(strstr(out, "one of 3 MPI ranks"));
    assert_non_null(strstr(out, "-DRHOSCAN_MPI=ON"));
    snprintf(work, sizeof work, "%s/work", dir);
    assert_int_not_equal(access(work, F_OK), 0); /* not even the work folder */
    free(out);
    rs_test_rmtree(dir);
}

static void test_misspelt_key(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cli");
    write_scene(dir, 64, 32, 0);
    const char *cfg = write_config(dir, "[reflectance]\nmethd = direct\n");
    const char *needles[] = {"scene.ini:13", "methd", "did you mean method", NULL};
    expect_failure(cfg, needles);
    rs_test_rmtree(dir);
}

static void test_bad_value_and_rotation(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cli");
    write_scene(dir, 64, 32, 0);
    const char *cfg = write_config(dir, "[reflectance]\nmethod = magic\n");
    const char *n1[] = {"scene.ini:13", "magic", "interreflection", NULL};
    expect_failure(cfg, n1);
    cfg = write_config(dir, "[capture.bad]\nrotation = 2 0 0 0 1 0 0 0 1\npanorama = pano.exr\n");
    const char *n2[] = {"scene.ini", "rotation", NULL};
    expect_failure(cfg, n2);
    rs_test_rmtree(dir);
}

static void test_missing_file(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cli");
    rs_test_write(rs_test_path(dir, "scene.ini"),
                  "[pipeline]\nworkdir = work\n[ingest]\nscan = nowhere.ptx\n[capture]\npanorama = pano.exr\n");
    const char *needles[] = {"nowhere.ptx", NULL};
    expect_failure(rs_test_path(dir, "scene.ini"), needles);
    char *out = NULL;
    assert_int_not_equal(run(rs_test_path(dir, "absent.ini"), NULL, &out), 0);
    assert_non_null(strstr(out, "absent.ini"));
    free(out);
    rs_test_rmtree(dir);
}

static void test_truncated_ptx(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cli");
    rs_test_write(rs_test_path(dir, "scan.ptx"),
                  "3\n3\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n1 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n"
                  "1 0 0 0.5\n1 1 0 0.5\n1 2 0 0.5\n2 0 0 0.5\n");
    rs_test_write(rs_test_path(dir, "scene.ini"),
                  "[pipeline]\nworkdir = work\n[ingest]\nscan = scan.ptx\n[capture]\npanorama = pano.exr\n");
    const char *needles[] = {"scan.ptx", NULL};
    expect_failure(rs_test_path(dir, "scene.ini"), needles);
    rs_test_rmtree(dir);
}

static void test_truncated_ply(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cli");
    write_scene(dir, 64, 32, 0);
    /* cut the mesh file in the middle of its faces */
    char *data;
    size_t size;
    FILE *f = fopen(rs_test_path(dir, "mesh.ply"), "rb");
    assert_non_null(f);
    fseek(f, 0, SEEK_END);
    size = (size_t)ftell(f);
    rewind(f);
    data = malloc(size);
    assert_int_equal(fread(data, 1, size, f), size);
    fclose(f);
    f = fopen(rs_test_path(dir, "mesh.ply"), "wb");
    fwrite(data, 1, size - 100, f);
    fclose(f);
    free(data);
    const char *needles[] = {"mesh.ply", "face", NULL};
    expect_failure(write_config(dir, NULL), needles);
    rs_test_rmtree(dir);
}

static void test_pano_not_2_to_1(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cli");
    write_scene(dir, 64, 48, 0);
    const char *needles[] = {"pano.exr", "64 x 48", "width = 2 x height", NULL};
    expect_failure(write_config(dir, NULL), needles);
    rs_test_rmtree(dir);
}

/* Non-finite pixels: a warning, a count in the metrics, and finite albedo everywhere. */
static void test_nonfinite_pixels(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cli");
    write_scene(dir, 256, 128, 500);
    char *out = NULL;
    int rc = run(write_config(dir, NULL), NULL, &out);
    if (rc != 0) print_message("%s", out);
    assert_int_equal(rc, 0);
    assert_non_null(strstr(out, "non-finite"));
    free(out);
    rs_err err;
    rs_ply *ply = rs_ply_read(rs_test_path(dir, "work/albedo.ply"), &err);
    assert_non_null(ply);
    rs_ply_element *faces = rs_ply_find_element(ply, "face");
    const char *names[] = {"albedo_r", "albedo_g", "albedo_b", "irradiance_sky_r", "irradiance_inter_r", "radiance_r"};
    size_t estimable = 0;
    for (int k = 0; k < 6; k++) {
        rs_ply_prop *p = rs_ply_find_prop(faces, names[k]);
        assert_non_null(p);
        for (size_t i = 0; i < faces->count; i++) assert_true(isfinite(p->data[i]));
    }
    rs_ply_prop *e = rs_ply_find_prop(faces, "estimable");
    for (size_t i = 0; i < faces->count; i++) estimable += e->data[i] > 0;
    assert_true(estimable > faces->count / 2);
    rs_ply_free(ply);
    rs_test_rmtree(dir);
}

/* A second run with nothing changed does no stage work; a change of method reruns only
 * reflectance and render. */
static void test_reruns(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cli");
    write_scene(dir, 128, 64, 0);
    const char *cfg = write_config(dir, NULL);
    char *out = NULL;
    assert_int_equal(run(cfg, NULL, &out), 0);
    free(out);
    assert_int_equal(run(cfg, NULL, &out), 0);
    assert_non_null(strstr(out, "every stage was up to date, nothing run"));
    /* Each skipped stage is said once as it is skipped, and once in the summary, unprefixed. */
    const char *first = strstr(out, "rhoscan: skipped stage mesh: ");
    assert_non_null(first);
    assert_null(strstr(first + 1, "rhoscan: skipped stage mesh: "));
    assert_non_null(strstr(out, "\n  stage mesh: inputs and config sections"));
    assert_null(strstr(out, "run: stage"));
    free(out);
    assert_int_equal(run(cfg, "--set reflectance.method=direct", &out), 0);
    assert_non_null(strstr(out, "skipped stage observe"));
    assert_non_null(strstr(out, "skipped stage irradiance"));
    assert_non_null(strstr(out, "reflectance: started"));
    assert_non_null(strstr(out, "render: started"));
    free(out);
    rs_test_rmtree(dir);
}

/* The option parser: --opt VALUE and --opt=VALUE alike, CONFIG among the options, and what
 * it refuses (an unknown option, a flag with a value, a value option without one, a second
 * CONFIG). */
static void test_options(void **state)
{
    (void)state;
    enum { FORCE, SET, HELP, COUNT };
    static const rs_option table[] = {[FORCE] = {"force", NULL, "run every stage"},
                                      [SET] = {"set", "s.k=v", "override a key"},
                                      [HELP] = {"help", NULL, "this text", 'h'},
                                      [COUNT] = {NULL}};
    char *argv[] = {"prog", "--set", "a.b=1", "CONFIG", "--set=c.d=2", "--force", "-h", NULL};
    rs_opt_scan s;
    rs_opt_begin(&s, table, 7, argv, 1);
    assert_int_equal(rs_opt_next(&s), SET);
    assert_string_equal(s.value, "a.b=1");
    assert_int_equal(rs_opt_next(&s), SET);
    assert_string_equal(s.value, "c.d=2");
    assert_int_equal(rs_opt_next(&s), FORCE);
    assert_null(s.value);
    assert_int_equal(rs_opt_next(&s), HELP);
    assert_int_equal(rs_opt_next(&s), RS_OPT_END);
    assert_string_equal(s.operand, "CONFIG");

    char *bad[][3] = {{"prog", "--forc", NULL},   {"prog", "--force=1", NULL}, {"prog", "--set", NULL},
                      {"prog", "--settle", NULL}, {"prog", "-", NULL},         {"prog", "--", NULL}};
    for (size_t k = 0; k < sizeof bad / sizeof *bad; k++) {
        rs_opt_begin(&s, table, 2, bad[k], 1);
        assert_int_equal(rs_opt_next(&s), RS_OPT_BAD);
        assert_string_equal(s.bad, bad[k][1]);
    }
    char *two[] = {"prog", "one.ini", "two.ini", NULL};
    rs_opt_begin(&s, table, 3, two, 1);
    assert_int_equal(rs_opt_next(&s), RS_OPT_BAD);
    assert_string_equal(s.bad, "two.ini");
    assert_string_equal(s.operand, "one.ini");
}

/* The driver takes --only=STAGE as --only STAGE (and checks the stage before reading CONFIG). */
static void test_run_options(void **state)
{
    (void)state;
    char *out = NULL;
    assert_int_equal(run("absent.ini", "--only=nosuch", &out), 1);
    assert_non_null(strstr(out, "rhoscan: unknown stage 'nosuch'"));
    free(out);
    assert_int_equal(run("absent.ini", "--frobnicate", &out), 1);
    assert_non_null(strstr(out, "rhoscan: unexpected argument '--frobnicate'"));
    free(out);
}

/* Every help and version form exits 0 and prints to stdout; a stage runs as `rhoscan STAGE`. */
static void test_help_version_and_stage_commands(void **state)
{
    (void)state;
    static const char *const forms[] = {
        "--help",    "-h", "help",    "help mesh",     "run --help",          "run -h", "mesh --help", "render -h",
        "--version", "-V", "version", "run --version", "irradiance --version"};
    char cmd[4096], *out = NULL;
    for (size_t k = 0; k < sizeof forms / sizeof *forms; k++) {
        snprintf(cmd, sizeof cmd, "'%s' %s 2>/dev/null", prog("rhoscan"), forms[k]);
        int rc = rs_test_run(cmd, &out);
        if (rc != 0 || !strstr(out, strstr(forms[k], "ersion") || !strcmp(forms[k], "-V") ? "rhoscan 0" : "usage:"))
            fail_msg("rhoscan %s: exit %d, printed '%.200s'", forms[k], rc, out);
        free(out);
    }
    snprintf(cmd, sizeof cmd, "'%s' --help", prog("rhoscan"));
    assert_int_equal(rs_test_run(cmd, &out), 0);
    assert_non_null(strstr(out, "rhoscan STAGE [OPTIONS] CONFIG"));
    assert_non_null(strstr(out, "given with --set, to the current folder"));
    assert_non_null(strstr(out, "--print-config"));
    free(out);
    snprintf(cmd, sizeof cmd, "'%s' frobnicate x.ini", prog("rhoscan"));
    assert_int_equal(rs_test_run(cmd, &out), 1);
    assert_non_null(strstr(out, "unknown command 'frobnicate'"));
    free(out);

    const char *dir = rs_test_tmpdir("cli");
    write_scene(dir, 128, 64, 0);
    const char *cfg = write_config(dir, NULL);
    snprintf(cmd, sizeof cmd, "'%s' ingest '%s'", prog("rhoscan"), cfg);
    assert_int_equal(rs_test_run(cmd, &out), 0);
    free(out);
    assert_int_equal(access(rs_test_path(dir, "work/ingest.json"), F_OK), 0);
    assert_int_not_equal(access(rs_test_path(dir, "work/mesh.json"), F_OK), 0); /* that stage alone */
    rs_test_rmtree(dir);
}

/* --print-config on run: every section in effect, each value with where it came from; it runs
 * nothing. metrics.json (read with cJSON) carries the same, and the --set overrides. */
static void test_effective_config(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cli");
    write_scene(dir, 128, 64, 0);
    const char *cfg = write_config(dir, NULL);
    char *out = NULL;
    assert_int_equal(run(cfg, "--print-config --set irradiance.seed=5 2>/dev/null", &out), 0);
    assert_non_null(strstr(out, "[irradiance]\nsamples = 64   ; file\n"));
    assert_non_null(strstr(out, "seed = 5   ; --set\n"));
    assert_non_null(strstr(out, "method = interreflection   ; default\n"));
    free(out);
    assert_int_not_equal(access(rs_test_path(dir, "work"), F_OK), 0);
    assert_int_equal(run(cfg, "--set=irradiance.seed=5", &out), 0);
    /* A uniform 0.5 everywhere makes the walls brighter than their sky allows: flagged, counted,
     * warned about; the 8-bit colours' encoding is stated in albedo.ply's header. */
    double above = rs_test_json_number(rs_test_path(dir, "work/reflectance.json"), "albedo_above_one");
    assert_true(above > 0);
    assert_non_null(strstr(out, "have an albedo above 1, impossible for a diffuse surface"));
    free(out);
    rs_err err;
    rs_ply *ply = rs_ply_read(rs_test_path(dir, "work/albedo.ply"), &err);
    assert_non_null(ply);
    size_t nf = rs_ply_find_element(ply, "face")->count, flagged = 0;
    double *flag = malloc(nf * sizeof *flag), *alb = malloc(3 * nf * sizeof *alb), *est = malloc(nf * sizeof *est);
    assert_int_equal(rs_faceprop_get(ply, "albedo.ply", "albedo_above_one", nf, flag, &err), 0);
    assert_int_equal(rs_faceprop_get(ply, "albedo.ply", "estimable", nf, est, &err), 0);
    assert_int_equal(rs_faceprop_get_rgb(ply, "albedo.ply", "albedo", nf, alb, &err), 0);
    /* The flag judges each facet's own albedo: pooling within its plane may bring a flagged
     * facet's written albedo below 1, but an albedo written above 1 is always flagged. */
    for (size_t i = 0; i < nf; i++) {
        int over = est[i] > 0 && (alb[3 * i] > 1 || alb[3 * i + 1] > 1 || alb[3 * i + 2] > 1);
        if (over) assert_true(flag[i] > 0);
        flagged += flag[i] > 0;
    }
    assert_int_equal(flagged, (size_t)above);
    free(flag);
    free(alb);
    free(est);
    rs_ply_free(ply);
    assert_non_null(strstr(rs_test_read_text(rs_test_path(dir, "work/albedo.ply")), "sRGB-encoded, 8 bit"));
    const struct cJSON *m = rs_test_json_file(rs_test_path(dir, "work/metrics.json"));
    assert_string_equal(rs_test_json_str(m, "effective_config/irradiance/samples/from"), "file");
    assert_string_equal(rs_test_json_str(m, "effective_config/reflectance/method/value"), "interreflection");
    assert_string_equal(rs_test_json_str(m, "effective_config/irradiance/seed/from"), "--set");
    const struct cJSON *set = rs_test_json_find(m, "set");
    assert_true(cJSON_IsArray(set) && cJSON_GetArraySize(set) == 1);
    assert_string_equal(cJSON_GetArrayItem(set, 0)->valuestring, "irradiance.seed=5");
    rs_test_rmtree(dir);
}

/* A stage whose work-folder input is missing says which stage writes it and what to run; a
 * failed first run leaves no work folder behind. */
static void test_missing_inputs(void **state)
{
    (void)state;
    const char *dir = rs_test_tmpdir("cli");
    write_scene(dir, 128, 64, 0);
    const char *cfg = write_config(dir, NULL);
    char cmd[4096], *out = NULL;
    snprintf(cmd, sizeof cmd, "'%s' render '%s'", prog("rhoscan"), cfg);
    assert_int_equal(rs_test_run(cmd, &out), 1);
    assert_non_null(strstr(out, "albedo.ply: cannot open"));
    assert_non_null(strstr(out, "the reflectance stage writes albedo.ply: run `rhoscan run"));
    free(out);
    assert_int_not_equal(access(rs_test_path(dir, "work"), F_OK), 0);
    const char *bad = rs_fx_write_scene_ini(dir, "0 -4 1.5", 64, 16, "[ingest]\nscan = missing.ptx\n");
    rs_test_write(bad, "[pipeline]\nworkdir = fresh\n[ingest]\nscan = missing.ptx\n[mesh]\nfacet_size = 0.3\n");
    assert_int_equal(run(bad, NULL, &out), 1);
    assert_non_null(strstr(out, "missing.ptx: cannot open"));
    free(out);
    assert_int_not_equal(access(rs_test_path(dir, "fresh"), F_OK), 0);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_misspelt_key), cmocka_unit_test(test_bad_value_and_rotation),
             cmocka_unit_test(test_missing_file), cmocka_unit_test(test_truncated_ptx),
             cmocka_unit_test(test_truncated_ply), cmocka_unit_test(test_pano_not_2_to_1),
             cmocka_unit_test(test_nonfinite_pixels), cmocka_unit_test(test_reruns), cmocka_unit_test(test_options),
             cmocka_unit_test(test_run_options), cmocka_unit_test(test_help_version_and_stage_commands),
             cmocka_unit_test(test_effective_config), cmocka_unit_test(test_missing_inputs),
             cmocka_unit_test(test_mpi_launch_without_mpi))

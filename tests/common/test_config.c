/* test_config: the config loader against its contract: defaults < file < --set, one message per
 * mistake (file, line, what was expected), capture.NAME sections, paths, round trips, KEYS.md. */
#include "tests/testutil.h"
#include "common/config.h"
#include "common/config_priv.h"

#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#define PI 3.14159265358979323846

static rs_config *load(const char *text, const char *const *overrides)
{
    rs_err err;
    rs_err_clear(&err);
    rs_config *cfg = rs_config_load_string(text, "tower.ini", "/base", overrides, &err);
    if (!cfg) fail_msg("unexpected error: %s:%ld: %s", err.file, err.line, err.msg);
    return cfg;
}

/* Loading must fail with an input error at file:line whose message contains needle. */
static void expect_error(const char *text, const char *const *overrides, const char *file, long line,
                         const char *needle)
{
    rs_err err;
    rs_err_clear(&err);
    rs_config *cfg = rs_config_load_string(text, "tower.ini", "/base", overrides, &err);
    if (cfg) {
        rs_config_free(cfg);
        fail_msg("loaded without error:\n%s", text);
    }
    assert_int_equal(err.kind, RS_ERR_INPUT);
    assert_string_equal(err.file, file);
    assert_int_equal(err.line, line);
    if (!strstr(err.msg, needle)) fail_msg("message \"%s\" lacks \"%s\"", err.msg, needle);
}

static void test_defaults(void **state)
{
    rs_config *cfg = load("", NULL);
    char path[RS_CFG_PATH_MAX];
    double v[9];
    assert_int_equal(rs_config_int(cfg, "pipeline", "threads"), 0);
    assert_int_equal(rs_config_int(cfg, "irradiance", "samples"), 256);
    assert_true(rs_config_real(cfg, "mesh", "max_depth_ratio") == 0.05);
    assert_true(rs_config_real(cfg, "render", "tolerance") == 1e-6);
    assert_true(isnan(rs_config_real(cfg, "mesh", "facet_size"))); /* no default */
    assert_false(rs_config_has(cfg, "mesh", "facet_size"));
    assert_false(rs_config_has(cfg, "irradiance", "samples"));
    assert_string_equal(rs_config_string(cfg, "reflectance", "method"), "interreflection");
    assert_string_equal(rs_config_path(cfg, "pipeline", "workdir", path, sizeof path), "/base/out");
    assert_null(rs_config_path(cfg, "mesh", "input_mesh", path, sizeof path));
    assert_int_equal(rs_config_path_count(cfg, "ingest", "scan"), 0);
    assert_int_equal(rs_config_reals(cfg, "capture", "rotation", v), 0);
    for (int i = 0; i < 9; i++) assert_true(v[i] == (i % 4 == 0));
    /* No default position: a forgotten camera pose must not read as the origin. */
    assert_int_equal(rs_config_reals(cfg, "capture.any", "position", v), -1);
    assert_int_equal(rs_config_sections(cfg, "capture", NULL, 0), 0);
    assert_string_equal(rs_config_file(cfg), "tower.ini");
    assert_string_equal(rs_config_dir(cfg), "/base");
    rs_config_free(cfg);
}

static void test_file_values_and_comments(void **state)
{
    const char *dir = rs_test_tmpdir("config");
    const char *file = rs_test_path(dir, "tower.ini");
    rs_test_write(file,
                  "; a comment\n# another\n[mesh]\n  facet_size = 0.5 ; half a metre\n"
                  "max_grazing_deg=80   # degrees\n[ reflectance ]\nmethod = direct\n"
                  "[irradiance]\r\nsamples = 100\r\n");
    rs_err err;
    rs_config *cfg = rs_config_load(file, NULL, &err);
    assert_non_null(cfg);
    assert_true(rs_config_real(cfg, "mesh", "facet_size") == 0.5);
    assert_true(rs_config_real(cfg, "mesh", "max_grazing_deg") == 80);
    assert_true(rs_config_has(cfg, "mesh", "facet_size"));
    assert_string_equal(rs_config_string(cfg, "reflectance", "method"), "direct");
    assert_int_equal(rs_config_int(cfg, "irradiance", "samples"), 100);
    assert_string_equal(rs_config_file(cfg), file);
    assert_string_equal(rs_config_dir(cfg), dir);
    rs_config_free(cfg);
    rs_test_rmtree(dir);
}

static void test_precedence(void **state)
{
    const char *text = "[irradiance]\nsamples = 100\nseed = 5\n";
    const char *ov[] = {"irradiance.samples=7", "irradiance.sun_samples = 3 ", "irradiance.seed=8", "irradiance.seed=9",
                        NULL};
    rs_config *cfg = load(text, ov);
    assert_int_equal(rs_config_int(cfg, "irradiance", "samples"), 7);      /* --set over file */
    assert_int_equal(rs_config_int(cfg, "irradiance", "sun_samples"), 3);  /* --set over default */
    assert_int_equal(rs_config_int(cfg, "irradiance", "seed"), 9);         /* the last --set wins */
    assert_true(rs_config_real(cfg, "irradiance", "sun_threshold") == 50); /* default */
    rs_config_free(cfg);
    cfg = load(text, NULL);
    assert_int_equal(rs_config_int(cfg, "irradiance", "samples"), 100); /* file over default */
    assert_int_equal(rs_config_int(cfg, "irradiance", "sun_samples"), 64);
    rs_config_free(cfg);
}

static void test_unknown_names(void **state)
{
    rs_err err;
    rs_config *cfg = rs_config_load_string("[mesh]\n\nfacet_sise = 0.1\n", "tower.ini", "/b", NULL, &err);
    assert_null(cfg);
    char line[2048];
    rs_err_format(&err, line, sizeof line);
    assert_string_equal(line, "tower.ini:3: [mesh] facet_sise: unknown key; did you mean facet_size?");
    expect_error("[capture]\nfacet_size = 1\n", NULL, "tower.ini", 2, "facet_size is a key of [mesh]");
    expect_error("[mesh]\nzzzzzzzzzzzz = 1\n", NULL, "tower.ini", 2,
                 "the keys of [mesh] are input_mesh, facet_size, pixels_per_facet");
    expect_error("[pipeline]\nthreads = 1\n[meshh]\nfacet_size = 1\n", NULL, "tower.ini", 3,
                 "unknown section [meshh]; did you mean [mesh]?");
    expect_error("[mesh]\n[nothing_like_it]\n", NULL, "tower.ini", 2, /* a section with no keys */
                 "the sections are [pipeline], [ingest], [mesh]");
    expect_error("[captur.north]\npanorama = a.exr\n", NULL, "tower.ini", 1, "did you mean [capture.north]?");
    expect_error("[mesh.fine]\nfacet_size = 1\n", NULL, "tower.ini", 1, "only [capture.NAME]");
    expect_error("[capture.]\n", NULL, "tower.ini", 1, "expected [capture.NAME]");
    expect_error("threads = 1\n[pipeline]\n", NULL, "tower.ini", 1, "outside any section");
    expect_error("[mesh]\n= 4\n", NULL, "tower.ini", 2, "no key name");
}

static void test_bad_values(void **state)
{
    expect_error("[mesh]\nfacet_size = -0.2\n", NULL, "tower.ini", 2,
                 "[mesh] facet_size = \"-0.2\": expected a real in [0.0001, 10000] (m)");
    expect_error("[mesh]\nfacet_size = 1 2\n", NULL, "tower.ini", 2, "expected a real");
    expect_error("[mesh]\nfacet_size = inf\n", NULL, "tower.ini", 2, "expected a real");
    expect_error("[mesh]\nfacet_size = nan\n", NULL, "tower.ini", 2, "expected a real");
    expect_error("[pipeline]\nthreads = 2.5\n", NULL, "tower.ini", 2,
                 "threads = \"2.5\": expected an integer in [0, 4096]");
    expect_error("[pipeline]\nthreads = 99999999999999999999999\n", NULL, "tower.ini", 2,
                 "expected an integer in [0, 4096]");
    expect_error("[pipeline]\nthreads = 4097\n", NULL, "tower.ini", 2, "expected an integer");
    expect_error("[reflectance]\nmethod = fast\n", NULL, "tower.ini", 2,
                 "method = \"fast\": expected one of interreflection, direct, paper");
    expect_error("[capture]\nposition = 1 2\n", NULL, "tower.ini", 2, "expected 3 finite reals (m); found 2 numbers");
    expect_error("[capture]\nposition = 1 2 nan\n", NULL, "tower.ini", 2, "\"nan\" is not a finite real");
    expect_error("[capture]\nrotation = 1 0 0 0 1 0 0 0\n", NULL, "tower.ini", 2,
                 "expected 9 finite reals (a rotation matrix, row-major); found 8 numbers");
    expect_error("[mesh]\ninput_mesh =\n", NULL, "tower.ini", 2, "expected a path");
    expect_error("[ingest]\nscan = ; nothing\n", NULL, "tower.ini", 2, "expected one or more paths");
    /* Lines libinih cannot read at all. */
    expect_error("[mesh]\n\nfacet_size\n", NULL, "tower.ini", 3, "\"facet_size\": expected \"key = value\"");
    expect_error("[pipeline]\nthreads = 1\n[mesh\n", NULL, "tower.ini", 3, "expected \"key = value\"");
    expect_error("[mesh]\nfacet_size = 1\n  continued\n", NULL, "tower.ini", 3, "\"  continued\"");
}

static void test_duplicates(void **state)
{
    expect_error("[mesh]\nfacet_size = 1\n\nfacet_size = 2\n", NULL, "tower.ini", 4,
                 "[mesh] facet_size is given twice, on lines 2 and 4");
    expect_error("[mesh]\nfacet_size = 1\n[pipeline]\nthreads=1\n[mesh]\nfacet_size = 1\n", NULL, "tower.ini", 6,
                 "on lines 2 and 6");
    /* The same key in two captures is no duplicate. */
    rs_config *cfg = load("[capture]\nposition = 1 2 3\n[capture.b]\nposition = 4 5 6\n", NULL);
    rs_config_free(cfg);
}

static void test_missing_and_binary_files(void **state)
{
    rs_err err;
    rs_err_clear(&err);
    assert_null(rs_config_load("/nonexistent/rhoscan/tower.ini", NULL, &err));
    assert_string_equal(err.file, "/nonexistent/rhoscan/tower.ini");
    assert_non_null(strstr(err.msg, "cannot open the config file"));
    assert_non_null(strstr(err.msg, "No such file"));
    const char *dir = rs_test_tmpdir("config");
    const char *file = rs_test_path(dir, "bin.ini");
    FILE *f = fopen(file, "wb");
    assert_non_null(f);
    fwrite("[mesh]\nfacet\0_size = 1\n", 1, 23, f);
    fclose(f);
    assert_null(rs_config_load(file, NULL, &err));
    assert_int_equal(err.line, 2);
    assert_non_null(strstr(err.msg, "NUL byte"));
    assert_null(rs_config_load(dir, NULL, &err)); /* a folder */
    assert_string_equal(err.file, dir);
    rs_test_rmtree(dir);
}

static void test_override_errors(void **state)
{
    const char *a[] = {"mesh.facet_sise=1", NULL};
    expect_error("", a, "--set", 0, "[mesh] facet_sise: unknown key; did you mean facet_size?");
    const char *b[] = {"facet_size=1", NULL};
    expect_error("", b, "--set", 0, "\"facet_size=1\": expected section.key=value");
    const char *c[] = {"mesh.facet_size", NULL};
    expect_error("", c, "--set", 0, "expected section.key=value");
    const char *d[] = {"mesh.facet_size=-1", NULL};
    expect_error("[mesh]\nfacet_size = 1\n", d, "--set", 0,
                 "[mesh] facet_size = \"-1\": expected a real in [0.0001, 10000] (m)");
    const char *e[] = {"capture.north.rotation=2 0 0 0 2 0 0 0 2", NULL};
    expect_error("", e, "--set", 0, "[capture.north] rotation = \"2 0 0 0 2 0 0 0 2\": not a rotation");
    const char *f[] = {"meshh.facet_size=1", NULL};
    expect_error("", f, "--set", 0, "did you mean [mesh]?");
}

static void test_capture_sections(void **state)
{
    const char *ov[] = {"capture.east.position=7 8 9", "capture.north.panorama=n2.exr", NULL};
    rs_config *cfg = load("[capture]\npanorama = main.exr\n[capture.north]\nposition = 1 2 3\n"
                          "panorama = n.exr\n[capture.south]\n[mesh]\n",
                          ov);
    const char *names[8];
    assert_int_equal(rs_config_sections(cfg, "capture", names, 8), 4);
    assert_string_equal(names[0], "capture");
    assert_string_equal(names[1], "capture.north");
    assert_string_equal(names[2], "capture.south"); /* present though empty */
    assert_string_equal(names[3], "capture.east");  /* named only by --set */
    assert_int_equal(rs_config_sections(cfg, "capture", names, 1), 4);
    assert_int_equal(rs_config_sections(cfg, "mesh", names, 8), 1);
    double p[3];
    assert_int_equal(rs_config_reals(cfg, "capture.north", "position", p), 0);
    assert_true(p[0] == 1 && p[1] == 2 && p[2] == 3);
    assert_int_equal(rs_config_reals(cfg, "capture.east", "position", p), 0);
    assert_true(p[0] == 7 && p[1] == 8 && p[2] == 9);
    assert_int_equal(rs_config_reals(cfg, "capture", "position", p), -1); /* unset, no default */
    char path[RS_CFG_PATH_MAX];
    char cwd[RS_CFG_PATH_MAX], want[RS_CFG_PATH_MAX + 16];
    assert_non_null(getcwd(cwd, sizeof cwd));
    snprintf(want, sizeof want, "%s/n2.exr", strcmp(cwd, "/") ? cwd : ""); /* --set: the current folder's */
    assert_string_equal(rs_config_path(cfg, "capture.north", "panorama", path, sizeof path), want);
    assert_string_equal(rs_config_path(cfg, "capture", "panorama", path, sizeof path), "/base/main.exr");
    assert_null(rs_config_path(cfg, "capture.south", "panorama", path, sizeof path));
    assert_false(rs_config_has(cfg, "capture.south", "position"));
    rs_config_free(cfg);
    expect_error("[capture.north]\nposition = 1 2 3\nrotaton = 1 0 0 0 1 0 0 0 1\n", NULL, "tower.ini", 3,
                 "[capture.north] rotaton: unknown key; did you mean rotation?");
}

static void test_rotation(void **state)
{
    double c = cos(PI / 6), s = sin(PI / 6), r[9];
    char text[512];
    snprintf(text, sizeof text, "[capture]\nrotation = %.17g %.17g 0  %.17g %.17g 0  0 0 1\n", c, -s, s, c);
    rs_config *cfg = load(text, NULL);
    assert_int_equal(rs_config_reals(cfg, "capture", "rotation", r), 0);
    assert_true(r[0] == c && r[1] == -s && r[3] == s && r[4] == c && r[8] == 1);
    rs_config_free(cfg);
    /* Rounded to 5 decimals: within the 1e-4 tolerance. Rounded to 2: not. Commas separate too. */
    rs_config_free(load("[capture]\nrotation = 0.86603, -0.5, 0, 0.5, 0.86603, 0, 0, 0, 1\n", NULL));
    expect_error("[capture]\nrotation = 0.87 -0.5 0 0.5 0.87 0 0 0 1\n", NULL, "tower.ini", 2,
                 "not a rotation: R^T R differs from the identity by up to 0.0069 (tolerance 0.0001)");
    expect_error("[capture]\nrotation = 2 0 0 0 2 0 0 0 2\n", NULL, "tower.ini", 2,
                 "\"2 0 0 0 2 0 0 0 2\": not a rotation: R^T R differs from the identity by up to 3");
    expect_error("[capture]\nrotation = 1 0 0 0 1 0 0 0 -1\n", NULL, "tower.ini", 2,
                 "not a rotation: its determinant is -1");
}

static void test_long_lines(void **state)
{
    /* A rotation about Z by 30 degrees, each number written with 40 digits: > 300 characters on
     * one line, which libinih's default 200-byte buffer would cut. */
    const char *cos30 = "0.8660254037844386467637231707529361834714";
    const char *sin30 = "0.5000000000000000000000000000000000000000";
    const char *zero = "0.0000000000000000000000000000000000000000";
    char text[2048], line[1024];
    snprintf(line, sizeof line, "rotation = %s -%s %s %s %s %s %s %s 1.%s", cos30, sin30, zero, sin30, cos30, zero,
             zero, zero, zero + 2);
    assert_true(strlen(line) > 300);
    snprintf(text, sizeof text, "[capture]\n%s\nposition = 1 2 3\n[mesh]\nfacet_sise = 1\n", line);
    expect_error(text, NULL, "tower.ini", 5, "did you mean facet_size?"); /* lines still counted */
    snprintf(text, sizeof text, "[capture]\n%s\nposition = 1 2 3\n", line);
    rs_config *cfg = load(text, NULL);
    double r[9], p[3];
    assert_int_equal(rs_config_reals(cfg, "capture", "rotation", r), 0);
    assert_true(r[0] == strtod(cos30, NULL) && r[1] == -0.5 && r[3] == 0.5 && r[8] == 1);
    assert_true(fabs(r[4] - cos(PI / 6)) < 1e-15);
    assert_int_equal(rs_config_reals(cfg, "capture", "position", p), 0);
    assert_true(p[2] == 3);
    rs_config_free(cfg);
    /* Beyond the limit: refused with the line, never split. */
    size_t n = 70000;
    char *huge = malloc(n + 64);
    assert_non_null(huge);
    int head = snprintf(huge, n, "[mesh]\nfacet_size = ");
    memset(huge + head, '1', n - (size_t)head);
    strcpy(huge + n, "\n");
    expect_error(huge, NULL, "tower.ini", 2, "expected at most 65000");
    free(huge);
}

static void test_paths(void **state)
{
    const char *dir = rs_test_tmpdir("config");
    char sub[1024], file[1200], want[RS_CFG_PATH_MAX + 64], path[RS_CFG_PATH_MAX];
    snprintf(sub, sizeof sub, "%s/sub", dir);
    assert_int_equal(mkdir(sub, 0755), 0);
    snprintf(file, sizeof file, "%s/./c.ini", sub);
    rs_test_write(file,
                  "[mesh]\ninput_mesh = ../meshes/m.ply\n[ingest]\n"
                  "scan = a.ptx   ./b/c.ply /abs/d.ply\n[capture]\npanorama = /x/../p.exr\n");
    const char *ov[] = {"pipeline.workdir=work", NULL};
    rs_err err;
    char cwd[RS_CFG_PATH_MAX];
    assert_non_null(getcwd(cwd, sizeof cwd));
    assert_int_equal(chdir(dir), 0); /* a --set path is relative to where the command was typed */
    rs_config *cfg = rs_config_load(file, ov, &err);
    assert_int_equal(chdir(cwd), 0);
    assert_non_null(cfg);
    assert_string_equal(rs_config_dir(cfg), sub);
    snprintf(want, sizeof want, "%s/meshes/m.ply", dir);
    assert_string_equal(rs_config_path(cfg, "mesh", "input_mesh", path, sizeof path), want);
    assert_int_equal(rs_config_path_count(cfg, "ingest", "scan"), 3);
    snprintf(want, sizeof want, "%s/a.ptx", sub);
    assert_string_equal(rs_config_path_at(cfg, "ingest", "scan", 0, path, sizeof path), want);
    snprintf(want, sizeof want, "%s/b/c.ply", sub);
    assert_string_equal(rs_config_path_at(cfg, "ingest", "scan", 1, path, sizeof path), want);
    assert_string_equal(rs_config_path_at(cfg, "ingest", "scan", 2, path, sizeof path), "/abs/d.ply");
    assert_string_equal(rs_config_path(cfg, "capture", "panorama", path, sizeof path), "/p.exr");
    snprintf(want, sizeof want, "%s/work", dir); /* the current folder's, not the config's (sub) */
    assert_string_equal(rs_config_path(cfg, "pipeline", "workdir", path, sizeof path), want);
    assert_int_equal(rs_config_origin(cfg, "pipeline", "workdir"), RS_CFG_FROM_SET);
    assert_int_equal(rs_config_origin(cfg, "mesh", "input_mesh"), RS_CFG_FROM_FILE);
    assert_int_equal(rs_config_origin(cfg, "irradiance", "samples"), RS_CFG_FROM_DEFAULT);
    assert_int_equal(rs_config_origin(cfg, "mesh", "facet_size"), RS_CFG_UNSET);
    rs_config_free(cfg);
    /* load_string: relative base_dir is taken from the current folder. */
    cfg = rs_config_load_string("[mesh]\ninput_mesh = m.ply\n", "s", "rel/", NULL, &err);
    assert_non_null(cfg);
    snprintf(want, sizeof want, "%s/rel/m.ply", strcmp(cwd, "/") ? cwd : "");
    assert_string_equal(rs_config_path(cfg, "mesh", "input_mesh", path, sizeof path), want);
    rs_config_free(cfg);
    assert_int_equal(rs_cfg_resolve("/a/b", "../../../c", path, sizeof path), 0);
    assert_string_equal(path, "/c");
    assert_int_equal(rs_cfg_resolve("/a", ".", path, sizeof path), 0);
    assert_string_equal(path, "/a");
    assert_int_equal(rs_cfg_resolve("/a", "bcdef", path, 5), -1);
    rs_test_rmtree(dir);
}

static void test_section_text(void **state)
{
    const char *ov[] = {"irradiance.samples=512", NULL};
    rs_config *cfg = load("[mesh]\ninput_mesh = m.ply\nmax_depth_ratio = 5e-2\npixels_per_facet = 6.50\n"
                          "[ingest]\nscan = a.ptx b.ptx\n[capture.north]\nposition = 1, 2.5, -3\n"
                          "rotation = 0 -1 0 1 0 0 0 0 1\n[reflectance]\nunobserved_albedo = 0.3\n",
                          ov);
    char *mesh = rs_config_section_text(cfg, "mesh");
    /* Table order, canonical numbers, absolute paths, unset keys without default left out. */
    assert_string_equal(mesh,
                        "[mesh]\ninput_mesh = /base/m.ply\npixels_per_facet = 6.5\n"
                        "max_depth_ratio = 0.05\nmax_grazing_deg = 85\ninput_refine = false\nsurface = poisson\nnormal_neighbours = 16\n"
                        "poisson_depth = 10\noverlap_tolerance = 0.03\nreport_points = 200000\n"
                        "fill_nadir = true\nnadir_max_rms = 0.02\ndenoise = true\ndenoise_iterations = 3\n"
                        "denoise_vertex_iterations = 10\ndenoise_sigma_r_deg = 1e+01\ndenoise_sigma_s = 1\n"
                        "denoise_max_move = 0.005\n");
    free(mesh);
    char *north = rs_config_section_text(cfg, "capture.north");
    assert_string_equal(north, "[capture.north]\nposition = 1 2.5 -3\nrotation = 0 -1 0 1 0 0 0 0 1\n");
    free(north);
    /* Every section reads back in elsewhere with the same values (so the same text again). */
    const char *sections[] = {"pipeline", "ingest",     "mesh",        "capture", "capture.north",
                              "observe",  "irradiance", "reflectance", "render",  NULL};
    for (int i = 0; sections[i]; i++) {
        char *text = rs_config_section_text(cfg, sections[i]);
        assert_non_null(text);
        rs_err err;
        rs_config *back = rs_config_load_string(text, "print-config", "/elsewhere", NULL, &err);
        if (!back) fail_msg("%s does not read back: %s:%ld: %s", text, err.file, err.line, err.msg);
        char *again = rs_config_section_text(back, sections[i]);
        assert_string_equal(text, again);
        free(again);
        free(text);
        if (strcmp(sections[i], "mesh") == 0) {
            assert_true(rs_config_real(back, "mesh", "max_depth_ratio") == 0.05);
            assert_true(rs_config_has(back, "mesh", "max_grazing_deg"));
        }
        if (strcmp(sections[i], "irradiance") == 0) assert_int_equal(rs_config_int(back, "irradiance", "samples"), 512);
        if (strcmp(sections[i], "ingest") == 0) {
            char path[RS_CFG_PATH_MAX];
            assert_string_equal(rs_config_path_at(back, "ingest", "scan", 1, path, sizeof path), "/base/b.ptx");
        }
        rs_config_free(back);
    }
    /* Reals survive exactly: a value that needs all 17 digits. */
    rs_config_free(cfg);
    cfg = load("[reflectance]\nunobserved_albedo = 0.1234567890123456789\n", NULL);
    char *text = rs_config_section_text(cfg, "reflectance");
    rs_config *back = load(text, NULL);
    assert_true(rs_config_real(back, "reflectance", "unobserved_albedo") ==
                rs_config_real(cfg, "reflectance", "unobserved_albedo"));
    free(text);
    rs_config_free(back);
    rs_config_free(cfg);
}

static void test_table_and_checker(void **state)
{
    /* Every default is valid for its own row; no key appears twice in a section. */
    for (const rs_cfg_key *k = rs_cfg_keys; k->section; k++) {
        rs_cfg_value v;
        char why[900];
        if (k->def && rs_cfg_parse(k, k->def, "/base", &v, why, sizeof why) != 0)
            fail_msg("default of [%s] %s: %s", k->section, k->key, why);
        if (k->def) rs_cfg_value_clear(&v);
        assert_true(k->min <= k->max);
        assert_non_null(k->help);
        for (const rs_cfg_key *o = k + 1; o->section; o++)
            assert_false(strcmp(k->section, o->section) == 0 && strcmp(k->key, o->key) == 0);
    }
    /* Types with no key in the table yet. */
    rs_cfg_key flag = {"x", "flag", RS_CFG_BOOL, "no", 0, 0, NULL, "", "", "h"};
    rs_cfg_key name = {"x", "name", RS_CFG_STRING, NULL, 0, 0, NULL, "", "", "h"};
    rs_cfg_value v;
    char why[900];
    const char *yes[] = {"true", "YES", "on", "1"}, *no[] = {"false", "No", "off", "0"};
    for (int i = 0; i < 4; i++) {
        assert_int_equal(rs_cfg_parse(&flag, yes[i], "/", &v, why, sizeof why), 0);
        assert_int_equal(v.b, 1);
        assert_int_equal(rs_cfg_parse(&flag, no[i], "/", &v, why, sizeof why), 0);
        assert_int_equal(v.b, 0);
    }
    assert_int_equal(rs_cfg_parse(&flag, "maybe", "/", &v, why, sizeof why), -1);
    assert_string_equal(why, "expected true/false, yes/no, on/off or 1/0");
    assert_int_equal(rs_cfg_parse(&name, "any text", "/", &v, why, sizeof why), 0);
    assert_int_equal(rs_cfg_distance("facet_sise", "facet_size"), 1);
    assert_int_equal(rs_cfg_distance("facte_size", "facet_size"), 2);
    assert_int_equal(rs_cfg_distance("", "abc"), 3);
}

/* Getters abort on programming errors: run each in a child process. */
static void test_getter_misuse_aborts(void **state)
{
    rs_config *cfg = load("", NULL);
    for (int which = 0; which < 4; which++) {
        pid_t pid = fork();
        assert_true(pid >= 0);
        if (pid == 0) {
            if (!freopen("/dev/null", "w", stderr)) _exit(2);
            char path[8];
            if (which == 0) rs_config_int(cfg, "mesh", "facet_size");                      /* wrong type */
            if (which == 1) rs_config_real(cfg, "mesh", "no_such_key");                    /* not in the table */
            if (which == 2) rs_config_has(cfg, "nosection", "x");                          /* unknown section */
            if (which == 3) rs_config_path(cfg, "pipeline", "workdir", path, sizeof path); /* short buffer */
            _exit(0);
        }
        int status;
        assert_int_equal(waitpid(pid, &status, 0), pid);
        assert_true(WIFSIGNALED(status) && WTERMSIG(status) == SIGABRT);
    }
    rs_config_free(cfg);
}

/* Garbage never crashes: random lines built from INI punctuation and real key names. */
static void test_garbage(void **state)
{
    static const char *parts[] = {
        "[", "]",    "=",   ";",     "#",  " ",  "\n",        ".",    "mesh", "capture", "facet_size",   "rotation",
        "1", "-0.5", "nan", "1e999", "\t", "\r", "capture.x", "scan", "..",   "/",       "\xEF\xBB\xBF", "position"};
    unsigned seed = 12345;
    char text[512];
    for (int iter = 0; iter < 3000; iter++) {
        size_t len = 0;
        int count = (int)((seed = seed * 1103515245u + 12345u) >> 16) % 40;
        for (int i = 0; i < count; i++) {
            const char *p = parts[((seed = seed * 1103515245u + 12345u) >> 16) % (sizeof parts / sizeof *parts)];
            if (len + strlen(p) + 1 >= sizeof text) break;
            memcpy(text + len, p, strlen(p));
            len += strlen(p);
        }
        text[len] = '\0';
        const char *ov[] = {text, NULL};
        rs_err err;
        rs_err_clear(&err);
        rs_config *cfg = rs_config_load_string(text, "g.ini", "/", iter % 2 ? ov : NULL, &err);
        if (cfg) {
            free(rs_config_section_text(cfg, "mesh"));
            rs_config_free(cfg);
        } else {
            assert_true(err.kind != RS_OK && err.msg[0] != '\0');
        }
    }
}

static void test_keys_md(void **state)
{
    char *md = rs_config_keys_markdown();
    assert_non_null(md);
    assert_non_null(strstr(md, "| `facet_size` | real in [0.0001, 10000] | m | *none* | mesh |"));
    assert_non_null(strstr(md, "## [capture]"));
    assert_non_null(strstr(md, "one of interreflection, direct, paper"));
    char path[2048];
    snprintf(path, sizeof path, "%s/configs/KEYS.md", rs_test_source_dir());
    const char *update = getenv("RHOSCAN_UPDATE_KEYS_MD");
    if (update && strcmp(update, "1") == 0) {
        rs_test_write(path, md);
        fprintf(stderr, "wrote %s\n", path);
    }
    FILE *f = fopen(path, "rb");
    if (!f) {
        free(md);
        fail_msg("cannot open %s", path);
    }
    size_t cap = strlen(md) + 2;
    char *file = malloc(cap);
    size_t n = fread(file, 1, cap - 1, f);
    file[n] = '\0';
    fclose(f);
    int same = strcmp(file, md) == 0;
    free(file);
    free(md);
    if (!same)
        fail_msg("%s differs from the key table (common/config_keys.c); rerun test_config with "
                 "RHOSCAN_UPDATE_KEYS_MD=1 to regenerate it, and review the diff",
                 path);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_defaults), cmocka_unit_test(test_file_values_and_comments),
             cmocka_unit_test(test_precedence), cmocka_unit_test(test_unknown_names), cmocka_unit_test(test_bad_values),
             cmocka_unit_test(test_duplicates), cmocka_unit_test(test_missing_and_binary_files),
             cmocka_unit_test(test_override_errors), cmocka_unit_test(test_capture_sections),
             cmocka_unit_test(test_rotation), cmocka_unit_test(test_long_lines), cmocka_unit_test(test_paths),
             cmocka_unit_test(test_section_text), cmocka_unit_test(test_table_and_checker),
             cmocka_unit_test(test_getter_misuse_aborts), cmocka_unit_test(test_garbage),
             cmocka_unit_test(test_keys_md))

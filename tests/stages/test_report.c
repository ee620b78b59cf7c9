/* The run report (pipeline/report.h, issue 23): its base64 and colour maps, and on the sample
 * run: the page and its images are written, the signed difference keeps its negatives (blue
 * where re-rendered < observed, red where above), `rhoscan report WORKDIR` rebuilds the page
 * without running a stage, [report] write = false leaves it alone, and a bad truth or folder is
 * named in the message. */
#include "tests/testutil.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "common/image.h"
#include "common/log.h"
#include "pipeline/report_html.h"
#include "pipeline/stage.h"

static const char *work;

static int setup(void **state)
{
    work = rs_test_tmpdir("report");
    char cmd[8192], *out = NULL;
    snprintf(cmd, sizeof cmd, "'%s/rhoscan' run '%s/configs/two_planes.ini' --set pipeline.workdir='%s' --quiet",
             rs_test_bin_dir(), rs_test_source_dir(), work);
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) print_message("%s\n", out ? out : "");
    free(out);
    return rc;
}

static int teardown(void **state)
{
    rs_test_rmtree(work);
    return 0;
}

static void test_base64(void **state)
{
    static const char *const in[] = {"", "f", "fo", "foo", "foob", "fooba", "foobar"};
    static const char *const want[] = {"", "Zg==", "Zm8=", "Zm9v", "Zm9vYg==", "Zm9vYmE=", "Zm9vYmFy"}; /* RFC 4648 */
    for (int k = 0; k < 7; k++) {
        rs_html h = {0};
        rs_html_put(&h, "");
        rs_html_base64(&h, (const unsigned char *)in[k], strlen(in[k]));
        assert_string_equal(h.s, want[k]);
        rs_html_release(&h);
    }
}

static void test_diverging_map(void **state)
{
    unsigned char c[3], lo[3], hi[3];
    rs_colormap_diverging(0.5, c); /* 0 is white */
    assert_true(c[0] > 240 && c[1] > 240 && c[2] > 240);
    rs_colormap_diverging(0, lo);
    rs_colormap_diverging(1, hi);
    assert_true(lo[2] > 2 * lo[0]);          /* negative end blue */
    assert_true(hi[0] > 2 * hi[2]);          /* positive end red */
    for (double t = 0; t < 0.5; t += 0.05) { /* equal distances from 0 are equally far from white */
        unsigned char a[3], b[3];
        rs_colormap_diverging(0.5 - t, a);
        rs_colormap_diverging(0.5 + t, b);
        int da = 3 * 247 - a[0] - a[1] - a[2], db = 3 * 247 - b[0] - b[1] - b[2];
        assert_true(abs(da - db) < 0.35 * (da + db) + 3);
    }
}

/* The whole page: with albedo.glb embedded it is megabytes, past rs_test_read_text's 64 KB. */
static char *read_page(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) fail_msg("cannot open %s", path);
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *s = malloc((size_t)n + 1);
    assert_non_null(s);
    assert_int_equal(fread(s, 1, (size_t)n, f), (size_t)n);
    s[n] = '\0';
    fclose(f);
    return s;
}

static void test_page_and_images(void **state)
{
    char *page = read_page(rs_test_path(work, "report.html"));
    static const char *const ids[] = {"id=\"views\"",    "id=\"plots\"",  "id=\"counts\"",    "id=\"stages\"",
                                      "id=\"warnings\"", "id=\"config\"", "id=\"provenance\""};
    for (size_t k = 0; k < sizeof ids / sizeof *ids; k++) assert_non_null(strstr(page, ids[k]));
    assert_null(strstr(page, "http://localhost")); /* nothing points off the machine */
    assert_null(strstr(page, "https://"));
    assert_non_null(strstr(page, "transport solve")); /* the residuals were plotted */
    static const char *const pngs[] = {"observed", "irradiance_sky", "irradiance_inter", "albedo",
                                       "synth",    "diff_signed",    "albedo_sigma",     "panorama_fill"};
    for (size_t k = 0; k < sizeof pngs / sizeof *pngs; k++) {
        char rel[128];
        snprintf(rel, sizeof rel, "report/%s.png", pngs[k]);
        assert_true(access(rs_test_path(work, rel), F_OK) == 0);
        assert_non_null(strstr(page, rel));
    }
    free(page);
}

/* The signed difference: every model pixel whose difference is clearly negative is blue, clearly
 * positive red; the sample has both (the old diff.png showed the negatives black). */
static void test_signed_difference(void **state)
{
    rs_err err;
    rs_image *diff = rs_image_read(rs_test_path(work, "diff.exr"), &err);
    rs_image *ids = rs_image_read(rs_test_path(work, "facet_id.exr"), &err);
    rs_image *png = rs_image_read(rs_test_path(work, "report/diff_signed.png"), &err);
    assert_non_null(diff);
    assert_non_null(ids);
    assert_non_null(png);
    assert_int_equal(png->width, diff->width); /* the sample's 512 x 256 is shown pixel for pixel */
    size_t n = (size_t)diff->width * diff->height, neg = 0, pos = 0;
    double big = 0;
    for (size_t k = 0; k < n; k++) {
        const float *d = diff->data + 3 * k;
        double y = 0.2126 * d[0] + 0.7152 * d[1] + 0.0722 * d[2];
        if (ids->data[k] >= 0 && fabs(y) > big) big = fabs(y);
    }
    for (size_t k = 0; k < n; k++) {
        const float *d = diff->data + 3 * k, *c = png->data + 3 * k;
        double y = 0.2126 * d[0] + 0.7152 * d[1] + 0.0722 * d[2];
        if (ids->data[k] < 0 || fabs(y) < 0.1 * big) continue;
        if (y < 0) {
            assert_true(c[2] > c[0]);
            neg++;
        } else {
            assert_true(c[0] > c[2]);
            pos++;
        }
    }
    assert_true(neg > 0 && pos > 0);
    rs_image_free(diff);
    rs_image_free(ids);
    rs_image_free(png);
}

static long mtime_ns(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 ? st.st_mtim.tv_sec * 1000000000L + st.st_mtim.tv_nsec : -1;
}

static void test_report_command(void **state)
{
    char cmd[8192], *out = NULL;
    const char *page = rs_test_path(work, "report.html");
    long render = mtime_ns(rs_test_path(work, "render.json"));
    assert_int_equal(unlink(page), 0);
    snprintf(cmd, sizeof cmd, "'%s/rhoscan' report '%s'", rs_test_bin_dir(), work);
    assert_int_equal(rs_test_run(cmd, &out), 0);
    free(out);
    assert_true(access(page, F_OK) == 0);
    assert_true(mtime_ns(rs_test_path(work, "render.json")) == render); /* no stage ran */
    snprintf(cmd, sizeof cmd, "'%s/rhoscan' report '%s/nowhere'", rs_test_bin_dir(), work);
    assert_int_equal(rs_test_run(cmd, &out), 1);
    assert_non_null(strstr(out, "nowhere"));
    free(out);
}

static void test_write_off_and_bad_truth(void **state)
{
    char cmd[8192], *out = NULL;
    const char *page = rs_test_path(work, "report.html");
    assert_int_equal(unlink(page), 0);
    snprintf(cmd, sizeof cmd,
             "'%s/rhoscan' render '%s/configs/two_planes.ini' --set pipeline.workdir='%s' --set "
             "report.write=false",
             rs_test_bin_dir(), rs_test_source_dir(), work);
    assert_int_equal(rs_test_run(cmd, &out), 0);
    free(out);
    assert_true(access(page, F_OK) != 0);
    const char *bad = rs_test_path(work, "bad_truth.ply");
    rs_test_write(bad, "ply\nformat ascii 1.0\nelement vertex 3\n");
    snprintf(cmd, sizeof cmd,
             "'%s/rhoscan' render '%s/configs/two_planes.ini' --set pipeline.workdir='%s' --set "
             "report.truth='%s'",
             rs_test_bin_dir(), rs_test_source_dir(), work, bad);
    assert_int_equal(rs_test_run(cmd, &out), 0); /* the stage's outputs stand; the report says why it is absent */
    assert_non_null(strstr(out, "bad_truth.ply"));
    assert_non_null(strstr(out, "report.html not written"));
    free(out);
}

/* A rhoscan-bench folder: run time against error with the Pareto front. Rows (time s, error):
 * a (1, 30 %), b (2, 10 %), c (3, 20 %: dominated by b), d (4, 5 %): the front is a, b, d. */
static void test_bench_pareto(void **state)
{
    const char *dir = rs_test_tmpdir("report_bench");
    rs_test_write(rs_test_path(dir, "bench.csv"),
                  "facets,row,t_total,albedo_err\n100,a,1,0.3\n100,b,2,0.1\n"
                  "100,c,3,0.2\n100,d,4,0.05\n");
    char cmd[8192], *out = NULL;
    snprintf(cmd, sizeof cmd, "'%s/rhoscan' report '%s'", rs_test_bin_dir(), dir);
    assert_int_equal(rs_test_run(cmd, &out), 0);
    free(out);
    const char *page = rs_test_read_text(rs_test_path(dir, "report.html"));
    const char *plot = strstr(page, "bench.csv: run time against albedo error");
    assert_non_null(plot);
    int circles = 0;
    for (const char *p = plot; (p = strstr(p, "<circle")); p++) circles++;
    assert_int_equal(circles, 4);
    /* the front: a step line through a, b and d: a, then two vertices per step down (b, d) */
    const char *line = strstr(plot, "<polyline");
    assert_non_null(line);
    const char *pts = strstr(line, "points=\"") + 8, *end = strchr(pts, '"');
    int vertices = 0;
    for (const char *p = pts; p < end; p++) vertices += *p == ',';
    assert_int_equal(vertices, 5);
    assert_non_null(strstr(plot, "c at 100 facets: 3, 20")); /* the dominated row is drawn, off the front */
    rs_test_rmtree(dir);
}

/* A stage that warns: the warning lands in its <stage>.json (the report's Warnings table), with
 * the CPU time beside the wall time. */
static int warning_stage(const rs_config *cfg, rs_report *rep, rs_err *err)
{
    rs_log_warn("test: something to look at (%d)", 42);
    return 0;
}

static void test_stage_warnings_recorded(void **state)
{
    const char *dir = rs_test_tmpdir("report_warn");
    const char *ini = rs_test_path(dir, "w.ini");
    char text[4200];
    snprintf(text, sizeof text, "[pipeline]\nworkdir = %s/work\n", dir);
    rs_test_write(ini, text);
    int rc = 0;
    const char *sets[] = {NULL};
    rs_config *cfg = rs_program_config(ini, sets, &rc);
    assert_non_null(cfg);
    rs_stage_def def = {"warner", warning_stage, "pipeline", "", "", "a stage that warns", 0};
    rs_err err;
    rs_err_clear(&err);
    assert_int_equal(rs_stage_execute(&def, cfg, NULL, &err), 0);
    const struct cJSON *j = rs_test_json_file(rs_test_path(dir, "work/warner.json"));
    const struct cJSON *w = rs_test_json_find(j, "warnings");
    assert_non_null(w);
    const char *page = rs_test_read_text(rs_test_path(dir, "work/warner.json"));
    assert_non_null(strstr(page, "test: something to look at (42)"));
    assert_true(rs_test_json_num(j, "cpu_time_s") >= 0);
    rs_config_free(cfg);
    rs_test_rmtree(dir);
}

RS_TEST_MAIN(setup, teardown, cmocka_unit_test(test_base64), cmocka_unit_test(test_diverging_map),
             cmocka_unit_test(test_page_and_images), cmocka_unit_test(test_signed_difference),
             cmocka_unit_test(test_report_command), cmocka_unit_test(test_write_off_and_bad_truth),
             cmocka_unit_test(test_bench_pareto), cmocka_unit_test(test_stage_warnings_recorded))

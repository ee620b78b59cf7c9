/* testutil: what the test programs share: temporary folders, the shared reference data
 * (skip when absent, fail under CI=true), running programs of the build. */
#ifndef RS_TESTUTIL_H
#define RS_TESTUTIL_H

#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#define RS_TEST_SKIP 77

/* A fresh temporary folder (removed by rs_test_rmtree); returns a static-lifetime string. */
const char *rs_test_tmpdir(const char *tag);
void rs_test_rmtree(const char *path);
/* dir/name in a static rotating buffer (8 slots). */
const char *rs_test_path(const char *dir, const char *name);
/* Writes text to a file; aborts the test on failure. */
void rs_test_write(const char *path, const char *text);

/* The whole text file (at most 64 KB) in a static buffer, valid until the next call; fails the
 * test when it cannot be read. */
const char *rs_test_read_text(const char *path);
/* JSON read with cJSON (Debian's libcjson), never by searching text. A key is found where it
 * first stands in the document (depth first, in file order); "outer/inner" finds inner's first
 * occurrence inside outer's value. The helpers fail the test when a key is absent. */
struct cJSON;
/* path's JSON, parsed; owned by the test utilities until the next call. */
const struct cJSON *rs_test_json_file(const char *path);
/* text parsed; owned by the test utilities until the next call. */
const struct cJSON *rs_test_json_text(const char *text);
/* The value of key under root, NULL when absent. */
const struct cJSON *rs_test_json_find(const struct cJSON *root, const char *key);
/* The number, string or three-number array of key under root (failing when absent or of
 * another type); the string is root's. */
double rs_test_json_num(const struct cJSON *root, const char *key);
const char *rs_test_json_str(const struct cJSON *root, const char *key);
void rs_test_json_vec3(const struct cJSON *root, const char *key, double v[3]);
/* The same straight from a stage's JSON file. */
double rs_test_json_number(const char *path, const char *key);
void rs_test_json_rgb(const char *path, const char *key, double v[3]);

/* RHOSCAN_SHARED_DIR when it exists. When it does not: prints why and exits 77 (ctest skip),
 * or exits 1 under CI=true, where the data must be there. */
const char *rs_test_shared_dir(void);
/* RHOSCAN_SHARED_DIR/rel when the variable is set and the file is there, else NULL (the test
 * then skips: skip()); a static buffer (4 slots). */
const char *rs_test_shared_file(const char *rel);
/* The source tree and the build tree (set by ctest). */
const char *rs_test_source_dir(void);
const char *rs_test_bin_dir(void);

/* Runs a shell command, capturing stderr+stdout into *output (caller frees); returns the exit
 * status (or -1). */
int rs_test_run(const char *cmd, char **output);

/* Runs the build's `rhoscan run --force SETS scene.ini` in dir; fails the test, printing the end
 * of the output (which says why), when it exits non-zero. */
void rs_test_rhoscan(const char *dir, const char *sets);
/* irradiance_sky (+ irradiance_inter when with_inter) of every facet in dir/work/irradiance.ply,
 * 3 per facet (caller frees); *nf: the facet count. */
double *rs_test_read_irradiance(const char *dir, int with_inter, size_t *nf);

/* A test program's main(): runs the tests given (cmocka_unit_test(name), ...) as one group, with
 * the group's setup and teardown (NULL: none); exits with the number of tests that failed. */
#define RS_TEST_MAIN(group_setup, group_teardown, ...)                     \
    int main(void)                                                         \
    {                                                                      \
        const struct CMUnitTest tests[] = {__VA_ARGS__};                   \
        return cmocka_run_group_tests(tests, group_setup, group_teardown); \
    }

#endif

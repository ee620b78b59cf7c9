/* test_nothing_lost: `rhoscan run` on the sample, killed with SIGKILL at several moments and
 * rerun, ends with data files (PLY, EXR) byte-identical to an uninterrupted run; one thread and
 * all cores give the same bytes; a full disk (RHOSCAN_FAULT=enospc:N) leaves the previous
 * outputs intact with a clear message; /dev/full as stdout or work folder is an error. */
#include "tests/testutil.h"

#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <time.h>

#include "common/fileio.h"

/* Fewer rays and facets than the sample's config: the same code paths, in a fraction of the time. */
#define SMALL                                                     \
    "--set mesh.pixels_per_facet=12 --set irradiance.samples=32 " \
    "--set irradiance.sky_samples=32 --set irradiance.sun_samples=8"

static char cmd_base[8192];

static int run(const char *workdir, const char *prefix, const char *extra, char **out)
{
    char cmd[16384];
    snprintf(cmd, sizeof cmd, "%s %s --set pipeline.workdir=%s %s 2>&1", prefix, cmd_base, workdir, extra);
    return rs_test_run(cmd, out);
}

static int data_file(const char *name)
{
    size_t n = strlen(name);
    return (n > 4 && (strcmp(name + n - 4, ".ply") == 0 || strcmp(name + n - 4, ".exr") == 0));
}

/* Every PLY and EXR of dir a has a byte-identical twin in dir b (and b has no other); returns
 * the number compared. */
static int compare_data(const char *a, const char *b, const char *what)
{
    DIR *d = opendir(a);
    assert_non_null(d);
    int count = 0;
    for (struct dirent *e; (e = readdir(d));) {
        if (!data_file(e->d_name)) continue;
        char pa[4096], pb[4096];
        char *da = NULL, *db = NULL;
        size_t na, nb;
        rs_err err;
        snprintf(pa, sizeof pa, "%s/%s", a, e->d_name);
        snprintf(pb, sizeof pb, "%s/%s", b, e->d_name);
        if (rs_read_file(pa, &da, &na, &err) != 0) fail_msg("%s", err.msg);
        if (rs_read_file(pb, &db, &nb, &err) != 0) fail_msg("%s: %s is missing (%s)", what, pb, err.msg);
        if (na != nb || memcmp(da, db, na) != 0) fail_msg("%s: %s differs from %s", what, pb, pa);
        free(da);
        free(db);
        count++;
    }
    closedir(d);
    d = opendir(b);
    for (struct dirent *e; (e = readdir(d));) {
        char pa[4096];
        snprintf(pa, sizeof pa, "%s/%s", a, e->d_name);
        if (data_file(e->d_name) && !rs_file_exists(pa)) fail_msg("%s: extra file %s", what, e->d_name);
    }
    closedir(d);
    return count;
}

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static void test_kill_rerun_determinism_full_disk(void **state)
{
    const char *tmp = rs_test_tmpdir("lost");
    snprintf(cmd_base, sizeof cmd_base, "%s/rhoscan run %s/configs/two_planes.ini " SMALL, rs_test_bin_dir(),
             rs_test_source_dir());
    char ref[4096], one[4096], killed[4096];
    snprintf(ref, sizeof ref, "%s/ref", tmp);
    snprintf(one, sizeof one, "%s/one", tmp);
    snprintf(killed, sizeof killed, "%s/killed", tmp);

    /* The reference: all cores, uninterrupted. */
    char *out = NULL;
    double t0 = now_s();
    int rc = run(ref, "", "", &out);
    double wall = now_s() - t0;
    if (rc != 0) fail_msg("reference run failed (%d):\n%s", rc, out);
    free(out);

    /* One thread: the same bytes. */
    rc = run(one, "", "--set pipeline.threads=1", &out);
    if (rc != 0) fail_msg("one-thread run failed (%d):\n%s", rc, out);
    free(out);
    int n = compare_data(ref, one, "threads=1 against all cores");
    print_message("determinism: %d data files identical with 1 thread and all cores\n", n);
    assert_true(n >= 8);

    /* SIGKILL at 10, 30, 55 and 85 % of the reference's wall time (inside different stages),
     * each on a fresh work folder, then a rerun to the end: the same bytes as the reference. */
    const double at[] = {0.10, 0.30, 0.55, 0.85};
    for (size_t k = 0; k < sizeof at / sizeof *at; k++) {
        char prefix[64];
        snprintf(killed, sizeof killed, "%s/killed%zu", tmp, k);
        snprintf(prefix, sizeof prefix, "timeout -s KILL %.2f", at[k] * wall);
        rc = run(killed, prefix, "", &out);
        free(out);
        int left = 0;
        DIR *d = opendir(killed);
        for (struct dirent *e; d && (e = readdir(d));) left += data_file(e->d_name);
        if (d) closedir(d);
        rc = run(killed, "", "", &out);
        if (rc != 0) fail_msg("rerun after the kill at %.1f s failed (%d):\n%s", at[k] * wall, rc, out);
        free(out);
        n = compare_data(ref, killed, "killed and rerun against uninterrupted");
        print_message("killed at %.1f s (%d data files written by then), rerun: %d data files identical\n",
                      at[k] * wall, left, n);
    }

    /* A full disk while the reflectance stage reruns (another method): its first write fails,
     * the run stops with exit 2 and a message naming the file, every earlier output stays. */
    rc = run(one, "RHOSCAN_FAULT=enospc:1", "--set reflectance.method=direct", &out);
    print_message("full disk: exit %d\n", rc);
    if (rc != 2 || !strstr(out, "No space left on device") || !strstr(out, "previous output kept"))
        fail_msg("expected exit 2 and 'No space left on device ... previous output kept', got %d:\n%s", rc, out);
    free(out);
    compare_data(ref, one, "after a failed write");
    /* The same change without the fault goes through and changes the albedo. */
    rc = run(one, "", "--set reflectance.method=direct", &out);
    if (rc != 0) fail_msg("run after the full disk failed (%d):\n%s", rc, out);
    free(out);

    /* /dev/full: as the work folder (not a folder) and as standard output. */
    rc = run("/dev/full/out", "", "", &out);
    if (rc == 0 || !strstr(out, "/dev/full/out")) fail_msg("work folder /dev/full/out: exit %d:\n%s", rc, out);
    free(out);
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "(%s/rhoscan-reflectance --print-config %s/configs/two_planes.ini >/dev/full)",
             rs_test_bin_dir(), rs_test_source_dir());
    rc = rs_test_run(cmd, &out);
    if (rc != 2 || !strstr(out, "cannot write to standard output"))
        fail_msg("--print-config > /dev/full: exit %d:\n%s", rc, out);
    free(out);
    rs_test_rmtree(tmp);
}

RS_TEST_MAIN(NULL, NULL, cmocka_unit_test(test_kill_rerun_determinism_full_disk))

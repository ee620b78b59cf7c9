/* testutil: helpers shared by the test programs (see testutil.h). */
#include "tests/testutil.h"

#include <cjson/cJSON.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>
#include "common/faceprop.h"
#include "common/ply.h"

const char *rs_test_tmpdir(const char *tag)
{
    static char dirs[8][512];
    static int next;
    char *d = dirs[next++ % 8];
    const char *base = getenv("TMPDIR") ? getenv("TMPDIR") : "/tmp";
    snprintf(d, sizeof dirs[0], "%s/rhoscan-%s-XXXXXX", base, tag);
    if (!mkdtemp(d)) {
        perror("mkdtemp");
        exit(1);
    }
    return d;
}

void rs_test_rmtree(const char *path)
{
    char cmd[1200];
    if (!path || !*path || strcmp(path, "/") == 0) return;
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", path);
    if (system(cmd) != 0) fprintf(stderr, "could not remove %s\n", path);
}

const char *rs_test_path(const char *dir, const char *name)
{
    static char buf[8][1024];
    static int next;
    char *b = buf[next++ % 8];
    snprintf(b, sizeof buf[0], "%s/%s", dir, name);
    return b;
}

void rs_test_write(const char *path, const char *text)
{
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    assert_int_equal(fwrite(text, 1, strlen(text), f), strlen(text));
    assert_int_equal(fclose(f), 0);
}

const char *rs_test_shared_file(const char *rel)
{
    static char buf[4][4096];
    static int next;
    const char *shared = getenv("RHOSCAN_SHARED_DIR");
    struct stat st;
    if (!shared) return NULL;
    char *b = buf[next++ % 4];
    snprintf(b, sizeof buf[0], "%s/%s", shared, rel);
    return stat(b, &st) == 0 ? b : NULL;
}

const char *rs_test_shared_dir(void)
{
    const char *d = getenv("RHOSCAN_SHARED_DIR");
    struct stat st;
    if (d && stat(d, &st) == 0 && S_ISDIR(st.st_mode)) return d;
    const char *ci = getenv("CI");
    if (ci && strcmp(ci, "true") == 0) {
        fprintf(stderr, "FAIL: shared data folder '%s' is missing, and CI=true requires it\n",
                d ? d : "(RHOSCAN_SHARED_DIR unset)");
        exit(1);
    }
    fprintf(stderr, "SKIP: shared data folder '%s' is missing (set -DRHOSCAN_SHARED_DIR=...)\n",
            d ? d : "(RHOSCAN_SHARED_DIR unset)");
    exit(RS_TEST_SKIP);
}

const char *rs_test_source_dir(void)
{
    const char *d = getenv("RHOSCAN_SOURCE_DIR");
    return d ? d : ".";
}

const char *rs_test_bin_dir(void)
{
    const char *d = getenv("RHOSCAN_BIN_DIR");
    return d ? d : ".";
}

int rs_test_run(const char *cmd, char **output)
{
    char full[8192];
    snprintf(full, sizeof full, "%s 2>&1", cmd);
    FILE *p = popen(full, "r");
    if (!p) return -1;
    size_t cap = 4096, len = 0;
    char *buf = malloc(cap);
    size_t n;
    while (buf && (n = fread(buf + len, 1, cap - len - 1, p)) > 0) {
        len += n;
        if (cap - len < 1024) {
            char *nb = realloc(buf, cap * 2);
            if (!nb) break;
            buf = nb;
            cap *= 2;
        }
    }
    if (buf) buf[len] = 0;
    int status = pclose(p);
    if (output)
        *output = buf;
    else
        free(buf);
    if (status == -1) return -1;
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

const char *rs_test_read_text(const char *path)
{
    static char buf[1 << 16];
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = 0;
    return buf;
}

static cJSON *json_held; /* the last document parsed: one at a time, freed by the next */

const cJSON *rs_test_json_text(const char *text)
{
    cJSON_Delete(json_held);
    json_held = cJSON_Parse(text);
    if (!json_held) fail_msg("not JSON (cJSON stops at: %.40s)", cJSON_GetErrorPtr() ? cJSON_GetErrorPtr() : "?");
    return json_held;
}

const cJSON *rs_test_json_file(const char *path)
{
    return rs_test_json_text(rs_test_read_text(path));
}

/* The first node below node, depth first, at the end of the path key ("a/b": a b inside an a;
 * every a is tried in turn). */
static const cJSON *find_path(const cJSON *node, const char *key)
{
    size_t n = strcspn(key, "/");
    for (const cJSON *c = node ? node->child : NULL; c; c = c->next) {
        if (c->string && strlen(c->string) == n && strncmp(c->string, key, n) == 0) {
            const cJSON *end = key[n] ? find_path(c, key + n + 1) : c;
            if (end) return end;
        }
        const cJSON *below = find_path(c, key);
        if (below) return below;
    }
    return NULL;
}

const cJSON *rs_test_json_find(const cJSON *root, const char *key)
{
    return *key ? find_path(root, key) : root;
}

static const cJSON *must_find(const cJSON *root, const char *key)
{
    const cJSON *v = rs_test_json_find(root, key);
    if (!v) fail_msg("JSON has no key \"%s\"", key);
    return v;
}

double rs_test_json_num(const cJSON *root, const char *key)
{
    const cJSON *v = must_find(root, key);
    if (!cJSON_IsNumber(v)) fail_msg("JSON key \"%s\" is not a number", key);
    return v->valuedouble;
}

const char *rs_test_json_str(const cJSON *root, const char *key)
{
    const cJSON *v = must_find(root, key);
    if (!cJSON_IsString(v)) fail_msg("JSON key \"%s\" is not a string", key);
    return v->valuestring;
}

void rs_test_json_vec3(const cJSON *root, const char *key, double v[3])
{
    const cJSON *a = must_find(root, key);
    if (!cJSON_IsArray(a) || cJSON_GetArraySize(a) < 3) fail_msg("JSON key \"%s\" is not an array of 3", key);
    for (int k = 0; k < 3; k++) {
        const cJSON *x = cJSON_GetArrayItem(a, k);
        if (!cJSON_IsNumber(x)) fail_msg("JSON key \"%s\"[%d] is not a number", key, k);
        v[k] = x->valuedouble;
    }
}

double rs_test_json_number(const char *path, const char *key)
{
    return rs_test_json_num(rs_test_json_file(path), key);
}

void rs_test_json_rgb(const char *path, const char *key, double v[3])
{
    rs_test_json_vec3(rs_test_json_file(path), key, v);
}

void rs_test_rhoscan(const char *dir, const char *sets)
{
    char cmd[8192], *out = NULL;
    snprintf(cmd, sizeof cmd, "cd '%s' && '%s/rhoscan' run --force %s scene.ini", dir, rs_test_bin_dir(), sets);
    int rc = rs_test_run(cmd, &out);
    if (rc != 0) { /* the end says why (print_message keeps 1 KB) */
        size_t n = out ? strlen(out) : 0;
        print_message("exit %d: ...%s\n", rc, out ? out + (n > 900 ? n - 900 : 0) : "");
    }
    assert_int_equal(rc, 0);
    free(out);
}

double *rs_test_read_irradiance(const char *dir, int with_inter, size_t *nf)
{
    rs_err err;
    const char *path = rs_test_path(dir, "work/irradiance.ply");
    rs_ply *ply = rs_ply_read(path, &err);
    assert_non_null(ply);
    const rs_ply_element *faces = rs_ply_find_element(ply, "face");
    assert_non_null(faces);
    *nf = faces->count;
    double *e = malloc(3 * *nf * sizeof *e), *g = malloc(3 * *nf * sizeof *g);
    assert_int_equal(rs_faceprop_get_rgb(ply, path, "irradiance_sky", *nf, e, &err), 0);
    assert_int_equal(rs_faceprop_get_rgb(ply, path, "irradiance_inter", *nf, g, &err), 0);
    for (size_t i = 0; with_inter && i < 3 * *nf; i++) e[i] += g[i];
    free(g);
    rs_ply_free(ply);
    return e;
}

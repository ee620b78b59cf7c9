/* json: the metrics files' tree, built and printed by cJSON (see json.h). An rs_json is a cJSON
 * item; this file only adds what the metrics need on top: numbers that are not finite become
 * null, a key set twice keeps its place and takes the last value, and files are written
 * atomically. */
#include "common/json.h"

#include <cjson/cJSON.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "common/fileio.h"

/* The handle callers hold is the cJSON item itself, seen through an incomplete type. */
#define CJ(j) ((cJSON *)(j))
#define RJ(c) ((rs_json *)(c))

rs_json *rs_json_object(void)
{
    return RJ(cJSON_CreateObject());
}

rs_json *rs_json_array(void)
{
    return RJ(cJSON_CreateArray());
}

void rs_json_free(rs_json *j)
{
    cJSON_Delete(CJ(j));
}

rs_json *rs_json_get(const rs_json *obj, const char *key)
{
    return cJSON_IsObject(CJ(obj)) ? RJ(cJSON_GetObjectItemCaseSensitive(CJ(obj), key)) : NULL;
}

/* Adds item as member key of obj, or puts it in the place of the member already there. */
static rs_json *set_item(rs_json *obj_handle, const char *key, cJSON *item)
{
    cJSON *obj = CJ(obj_handle);
    if (!item) return NULL;
    if (!cJSON_IsObject(obj)) {
        cJSON_Delete(item);
        return NULL;
    }
    int ok = cJSON_GetObjectItemCaseSensitive(obj, key) ? cJSON_ReplaceItemInObjectCaseSensitive(obj, key, item)
                                                        : cJSON_AddItemToObject(obj, key, item);
    if (!ok) {
        cJSON_Delete(item);
        return NULL;
    }
    return RJ(item);
}

static rs_json *push_item(rs_json *arr, cJSON *item)
{
    if (!item) return NULL;
    if (!cJSON_IsArray(CJ(arr)) || !cJSON_AddItemToArray(CJ(arr), item)) {
        cJSON_Delete(item);
        return NULL;
    }
    return RJ(item);
}

static cJSON *number(double v)
{
    return isfinite(v) ? cJSON_CreateNumber(v) : cJSON_CreateNull(); /* JSON has no NaN */
}

rs_json *rs_json_set_num(rs_json *obj, const char *key, double v)
{
    return set_item(obj, key, number(v));
}

rs_json *rs_json_set_int(rs_json *obj, const char *key, long long v)
{
    return set_item(obj, key, cJSON_CreateNumber((double)v));
}

rs_json *rs_json_set_str(rs_json *obj, const char *key, const char *s)
{
    return set_item(obj, key, cJSON_CreateString(s ? s : ""));
}

rs_json *rs_json_set_bool(rs_json *obj, const char *key, int b)
{
    return set_item(obj, key, cJSON_CreateBool(b != 0));
}

rs_json *rs_json_set_parsed(rs_json *obj, const char *key, const char *json_text)
{
    return set_item(obj, key, cJSON_Parse(json_text));
}

rs_json *rs_json_set_obj(rs_json *obj, const char *key)
{
    return set_item(obj, key, cJSON_CreateObject());
}

rs_json *rs_json_set_arr(rs_json *obj, const char *key)
{
    return set_item(obj, key, cJSON_CreateArray());
}

rs_json *rs_json_push_num(rs_json *arr, double v)
{
    return push_item(arr, number(v));
}

rs_json *rs_json_push_str(rs_json *arr, const char *s)
{
    return push_item(arr, cJSON_CreateString(s ? s : ""));
}

rs_json *rs_json_push_obj(rs_json *arr)
{
    return push_item(arr, cJSON_CreateObject());
}

char *rs_json_text(const rs_json *j)
{
    char *text = cJSON_Print(CJ(j));
    if (!text) return NULL;
    size_t n = strlen(text);
    char *out = malloc(n + 2); /* the caller frees with free(), not cJSON_free */
    if (out) {
        memcpy(out, text, n);
        out[n] = '\n';
        out[n + 1] = 0;
    }
    cJSON_free(text);
    return out;
}

int rs_json_write(const rs_json *j, const char *path, rs_err *err)
{
    char *text = rs_json_text(j);
    if (!text) return rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory formatting JSON");
    int rc = rs_write_file_atomic(path, text, strlen(text), err);
    free(text);
    return rc;
}

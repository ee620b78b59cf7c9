/* json: the tree of the metrics files (<stage>.json, metrics.json), built and printed by cJSON
 * (Debian's libcjson). Objects keep insertion order; numbers that are not finite are written
 * as null (JSON has no NaN); numbers are printed so that they read back to the same double. */
#ifndef RS_JSON_H
#define RS_JSON_H

#include <stddef.h>
#include "common/err.h"

typedef struct rs_json rs_json;   /* opaque: a cJSON item inside json.c */

rs_json *rs_json_object(void);
rs_json *rs_json_array(void);
void rs_json_free(rs_json *j);

/* Object setters (a key set twice keeps the last value); return the value added. */
rs_json *rs_json_set_num(rs_json *obj, const char *key, double v);
rs_json *rs_json_set_int(rs_json *obj, const char *key, long long v);
rs_json *rs_json_set_str(rs_json *obj, const char *key, const char *s);
rs_json *rs_json_set_bool(rs_json *obj, const char *key, int b);
/* json_text parsed and set under key (NULL when it does not parse): so that a stage's record
 * merged into metrics.json is indented like the rest. */
rs_json *rs_json_set_parsed(rs_json *obj, const char *key, const char *json_text);
rs_json *rs_json_set_obj(rs_json *obj, const char *key);                        /* new empty object under key */
rs_json *rs_json_set_arr(rs_json *obj, const char *key);                        /* new empty array under key */
/* Array appenders. */
rs_json *rs_json_push_num(rs_json *arr, double v);
rs_json *rs_json_push_str(rs_json *arr, const char *s);
rs_json *rs_json_push_obj(rs_json *arr);

/* Looks up a member of an object (NULL if absent). */
rs_json *rs_json_get(const rs_json *obj, const char *key);

/* Pretty text (indented by tabs, as cJSON prints; a trailing newline). Caller frees with free(). */
char *rs_json_text(const rs_json *j);
int rs_json_write(const rs_json *j, const char *path, rs_err *err); /* atomic */

#endif

/* ply: read and write PLY files (ascii, binary_little_endian; binary_big_endian read too)
 * with any elements, any scalar properties and list properties, held in memory as doubles.
 * Element and property names are kept as in the file; comments are kept in order. */
#ifndef RS_PLY_H
#define RS_PLY_H

#include <stddef.h>
#include "common/err.h"

typedef enum {
    RS_PLY_INT8,
    RS_PLY_UINT8,
    RS_PLY_INT16,
    RS_PLY_UINT16,
    RS_PLY_INT32,
    RS_PLY_UINT32,
    RS_PLY_FLOAT32,
    RS_PLY_FLOAT64
} rs_ply_type;

typedef struct rs_ply_prop {
    char name[64];
    rs_ply_type type; /* scalar type, or the type of a list's items */
    int is_list;
    rs_ply_type count_type; /* list only: type of the item count */
    double *data;           /* scalar: one value per element; list: all items back to back */
    size_t *offsets;        /* list only: element k's items are data[offsets[k] .. offsets[k+1]) */
} rs_ply_prop;

typedef struct rs_ply_element {
    char name[64];
    size_t count;
    int nprops;
    rs_ply_prop *props;
} rs_ply_element;

typedef struct rs_ply {
    int nelements;
    rs_ply_element *elements;
    int ncomments;
    char **comments; /* without the leading "comment " */
} rs_ply;

rs_ply *rs_ply_new(void);
void rs_ply_free(rs_ply *ply); /* NULL is fine */

/* Reads a file. Every failure names the file, the header line or the element index,
 * and what was expected: bad magic, unknown type, counts that disagree with the data,
 * truncated data, non-numeric ascii tokens, trailing garbage is ignored. Caller frees. */
rs_ply *rs_ply_read(const char *path, rs_err *err);
/* Same, from memory (for fuzzing); name is used in messages. */
rs_ply *rs_ply_read_mem(const char *data, size_t size, const char *name, rs_err *err);

/* Writes atomically (temporary file, then rename). binary: 1 little-endian, 0 ascii.
 * Values are converted to each property's type (rounded for integers, saturated to its range). */
int rs_ply_write(const rs_ply *ply, const char *path, int binary, rs_err *err);

/* Builders. Returned pointers are borrowed: valid while ply lives and until the next add
 * on the same ply (element) since arrays may move. */
rs_ply_element *rs_ply_add_element(rs_ply *ply, const char *name, size_t count);
/* Adds a scalar property, copying count values from values (or zeros when values is NULL). */
rs_ply_prop *rs_ply_add_scalar(rs_ply_element *el, const char *name, rs_ply_type type, const double *values);
/* Same from floats. */
rs_ply_prop *rs_ply_add_scalar_f(rs_ply_element *el, const char *name, rs_ply_type type, const float *values);
/* Adds a list property of fixed length n per element (triangles: n = 3) from items[count * n]. */
rs_ply_prop *rs_ply_add_list_fixed(rs_ply_element *el, const char *name, rs_ply_type count_type, rs_ply_type item_type,
                                   int n, const double *items);
int rs_ply_add_comment(rs_ply *ply, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* Streaming, for elements too big to hold as doubles (the transport kernel: 10^7 to 10^8
 * records). A record callback gets or gives the values of element el's record k, one per
 * property in declaration order (scalar properties only); it returns 0, or -1 with err set. */
typedef int (*rs_ply_record_fn)(void *ctx, const rs_ply_element *el, size_t k, double *values, rs_err *err);
/* Declares a scalar property whose values rs_ply_write_records asks of its callback: no data. */
rs_ply_prop *rs_ply_declare_scalar(rs_ply_element *el, const char *name, rs_ply_type type);
/* As rs_ply_write, but the records of every element whose properties were declared without data
 * come from fn, one at a time, in order; the bytes written are the same as rs_ply_write's. */
int rs_ply_write_records(const rs_ply *ply, const char *path, int binary, rs_ply_record_fn fn, void *ctx, rs_err *err);
/* Reads a file record by record, handing each to fn (values: one double per property, in order)
 * without keeping them: a binary file of scalar properties is read in blocks, never whole. Other
 * files (ascii, list properties) are read whole and then handed over, so any valid PLY works.
 * header (may be NULL) receives the header (elements, properties, comments; no data), which
 * the caller frees. The same checks and messages as rs_ply_read. */
int rs_ply_read_records(const char *path, rs_ply_record_fn fn, void *ctx, rs_ply **header, rs_err *err);

/* Look-ups; NULL when absent. */
rs_ply_element *rs_ply_find_element(const rs_ply *ply, const char *name);
rs_ply_prop *rs_ply_find_prop(const rs_ply_element *el, const char *name);
/* The value of comment "KEY rest" as "rest", or NULL. */
const char *rs_ply_find_comment(const rs_ply *ply, const char *key);

#endif

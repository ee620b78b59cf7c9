/* e57_internal: what the E57 reader's files share (common/e57.c, e57_file.c, e57_xml.c,
 * e57_points.c); not for other modules, which use common/e57.h. */
#ifndef RS_E57_INTERNAL_H
#define RS_E57_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "common/e57.h"
#include "common/err.h"

#define E57_PAGE       1024
#define E57_PAGE_DATA  1020
#define E57_CACHE_PAGE 128 /* pages read (and checked) at a time */

/* The paged file: logical offsets skip each page's 4-byte CRC. */
typedef struct e57_file {
    const char *name;
    int fd;             /* -1 when reading memory */
    const uint8_t *mem; /* the bytes, when reading memory */
    uint64_t size;      /* the file's bytes (a multiple of the page size) */
    uint64_t npages;
    uint8_t *cache;       /* E57_CACHE_PAGE pages, their CRCs checked */
    uint64_t cache_first; /* first page in the cache */
    uint64_t cache_n;     /* pages held (0: empty) */
} e57_file;

int e57_file_open(e57_file *f, const char *path, const void *mem, size_t size, rs_err *err);
void e57_file_close(e57_file *f);
/* n bytes at a logical offset, through the checked pages. */
int e57_read_logical(e57_file *f, uint64_t logical, void *buf, size_t n, rs_err *err);
/* The logical offset of a physical one; -1 (with err set, what naming it) when it points into
 * a CRC or past the file. */
int e57_logical_of(const e57_file *f, uint64_t physical, const char *what, uint64_t *logical, rs_err *err);
/* The logical length of the file (every page's data bytes). */
static inline uint64_t e57_logical_size(const e57_file *f)
{
    return f->npages * E57_PAGE_DATA;
}

/* An XML element of the E57 tree. */
typedef enum {
    E57_T_NONE,
    E57_T_STRUCT,
    E57_T_VECTOR,
    E57_T_CVECTOR,
    E57_T_INTEGER,
    E57_T_SCALED,
    E57_T_FLOAT,
    E57_T_STRING,
    E57_T_BLOB
} e57_type;

typedef struct e57_node {
    char *name;
    e57_type type;
    char *text; /* the element's character data, NUL-terminated ("" if none) */
    size_t text_len;
    char **attrs; /* name, value pairs, NULL-terminated */
    long line;
    struct e57_node *parent, *child, *next, *last; /* last: the last child */
    int nchildren;
    int index; /* its place among its parent's children */
} e57_node;

/* Parses the XML section; returns the root (e57Root) or NULL. */
e57_node *e57_xml_parse(const char *xml, size_t n, const char *file, rs_err *err);
void e57_xml_free(e57_node *root);
/* The child of a Structure by name, or NULL. */
e57_node *e57_child(const e57_node *n, const char *name);
/* The i-th child (Vector), or NULL. */
e57_node *e57_child_at(const e57_node *n, int i);
const char *e57_attr(const e57_node *n, const char *name);
/* The element's path from the root, e.g. "/data3D/0/points/prototype/cartesianX". */
void e57_path(const e57_node *n, char *buf, size_t size);

/* Values of typed elements; an empty element is 0 (the standard's default). Each returns -1
 * with err set (naming the XML path and line) when the element is not of a numeric type or its
 * text is not a number. */
int e57_number(const e57_node *n, const char *file, double *out, rs_err *err);
int e57_integer(const e57_node *n, const char *file, int64_t *out, rs_err *err);
/* A child's number, def when the child is absent. */
int e57_child_number(const e57_node *n, const char *name, double def, const char *file, double *out, rs_err *err);
/* A String child's text (copied into buf, cut to its size), "" when absent. */
void e57_child_string(const e57_node *n, const char *name, char *buf, size_t size);
/* An attribute as an integer (def when absent); -1 with err set when it is not one. */
int e57_attr_int(const e57_node *n, const char *attr, int64_t def, const char *file, int64_t *out, rs_err *err);
int e57_attr_real(const e57_node *n, const char *attr, double def, const char *file, double *out, rs_err *err);

/* A pose structure (rotation quaternion, translation) into R (row-major) and t: missing parts
 * are identity and zero; a quaternion that is not unit length is normalised with a warning. */
int e57_pose(const e57_node *pose, const char *file, double R[9], double t[3], rs_err *err);

/* The roles of prototype fields the reader uses. */
enum {
    E57_R_NONE,
    E57_R_X,
    E57_R_Y,
    E57_R_Z,
    E57_R_RANGE,
    E57_R_AZ,
    E57_R_EL,
    E57_R_CINV,
    E57_R_SINV,
    E57_R_ROW,
    E57_R_COL,
    E57_R_INT,
    E57_R_RED,
    E57_R_GREEN,
    E57_R_BLUE,
    E57_R_NX,
    E57_R_NY,
    E57_R_NZ,
    E57_R_NROLES
};

/* One leaf of the prototype: its bytestream and how to decode it. */
typedef struct e57_field {
    char path[160];
    int role;
    e57_type type;
    int bits;             /* per record in the bytestream */
    int64_t min, max;     /* Integer and ScaledInteger */
    double scale, offset; /* ScaledInteger */
    uint8_t *buf;         /* its bytes not yet decoded (with 8 bytes of slack) */
    size_t len, cap;
    uint64_t bit; /* the first undecoded bit in buf */
} e57_field;

/* A compressed vector being read. */
typedef struct e57_cv {
    e57_field *fields;
    int nfields;
    uint64_t records, done; /* recordCount, records decoded */
    uint64_t next_packet;   /* logical offset of the next packet */
    uint64_t section_end;   /* logical end of the binary section */
    uint64_t packets;       /* data packets read */
    uint8_t *packet;        /* one packet */
    char path[160];         /* the CompressedVector's XML path */
} e57_cv;

/* Prepares cv from a CompressedVector element: its prototype's leaves (roles from role_of, NULL
 * for all E57_R_NONE), its codecs (bitPackCodec only), its binary section's header. */
int e57_cv_open(e57_cv *cv, e57_file *f, const e57_node *node, int (*role_of)(const char *name), rs_err *err);
void e57_cv_free(e57_cv *cv);
/* Decodes up to max records: out[role] (for roles present, NULL otherwise) gets each value as a
 * double. Returns the records decoded (0 at the end) or -1. */
long e57_cv_read(e57_cv *cv, e57_file *f, double *const out[E57_R_NROLES], size_t max, rs_err *err);

#endif

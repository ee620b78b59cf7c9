/* freespace: what the scanners and the cameras say about empty space, and the faces that close
 * the model where they said nothing (docs/PIPELINE.md, irradiance: "Unknown space blocks light").
 *
 * A dense grid of 2 bits per cell over the model's bounding box grown by a margin: bit 0 "a
 * scanner or camera ray crossed this cell" (free), bit 1 "a surface lies in it" (occupied).
 * Rays are carved by a 3D-DDA (Amanatides and Woo 1987); cells are set with an atomic OR, so
 * carving runs on every OpenMP thread and the result does not depend on their order. A cell
 * neither free nor occupied is unknown. The occluders are the faces between a known cell (free
 * or occupied) and an unknown one, merged into rectangles per grid plane, each facing the known
 * side, each with a proxy whose radiance stands for the unseen surface's: the scanned facet nearest
 * to the unknown cell behind its centre among those facing the face's way (RS_FS_PROXY_COS). The
 * nearest facet whatever its facing was the tower sample's error: the unseen top of a cornice
 * scanned from below took its dark underside's radiance. */
#ifndef RS_FREESPACE_H
#define RS_FREESPACE_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"
#include "common/mesh.h"
#include "common/vec.h"

enum { RS_FS_UNKNOWN = 0, RS_FS_FREE = 1, RS_FS_OCCUPIED = 2 };

typedef struct rs_freespace {
    int n[3];         /* cells per axis */
    double lo[3];     /* the grid's lower corner, m */
    double cell;      /* cell edge, m */
    uint8_t *bits;    /* 2 bits per cell, 4 cells per byte, x fastest */
    size_t ncells;    /* n[0] n[1] n[2] */
    double carved;    /* rays carved */
    double carve_len; /* cells visited by carving */
    size_t opened;    /* unknown cells rs_freespace_occluders took as open (beyond its depth) */
} rs_freespace;

typedef struct rs_freespace_opts {
    double cell;      /* cell edge, m (> 0) */
    double margin;    /* the box grows by this in x, y and downward, m; its top is the model's */
    size_t max_cells; /* the cell edge grows (by 2^(1/3) steps) until the grid has at most this many */
} rs_freespace_opts;

/* The grid over mesh m's box (grown as opts say), every cell unknown, then every facet of m
 * sampled at a third of a cell: its cells occupied. -1 with err when out of memory. */
int rs_freespace_init(rs_freespace *fs, const rs_mesh *m, const rs_freespace_opts *opts, rs_err *err);
void rs_freespace_release(rs_freespace *fs);

/* Marks the cells on the segment from a to b free, up to half a cell short of b when hit is 1
 * (b is the surface the ray returned from), through to the grid's edge along a -> b when
 * to_edge is 1 (a ray that saw sky; b then only gives the direction). Thread-safe. */
void rs_freespace_carve(rs_freespace *fs, rs_v3 a, rs_v3 b, int to_edge);

/* The state of the cell holding p (RS_FS_*); points outside the grid are free (open sky). */
int rs_freespace_state(const rs_freespace *fs, rs_v3 p);
/* The state of cell (i, j, k) inside the grid. */
int rs_freespace_cell(const rs_freespace *fs, int i, int j, int k);

typedef struct rs_freespace_counts {
    size_t free, occupied, unknown;
} rs_freespace_counts;
void rs_freespace_count(const rs_freespace *fs, rs_freespace_counts *c);

/* label[cell] = the facet of m sampled into it (the later one in file order where several are),
 * of the facets use[] marks (every facet when use is NULL); other cells keep what they held.
 * Returns the facets sampled. */
size_t rs_freespace_label(const rs_freespace *fs, const rs_mesh *m, const uint8_t *use, uint32_t *label);

/* A facet may stand for an unseen surface facing an occluder face's way when its normal lies
 * within 60 degrees of the face's (cos 0.5; every normal is within 54.7 degrees of one of the six
 * axis directions, so every facet can stand for some face). */
#define RS_FS_PROXY_COS 0.5

/* Which unknown cells block (rs_freespace_occluders). */
typedef enum rs_fs_keep {
    /* every unknown cell within depth of a facet's cell: also the air over unseen ground and the
     * shadow wedge beside a column or above a lintel, which fattens them (the courtyard sample) */
    RS_FS_KEEP_NEAR = 0,
    /* only the unknown cells behind a scanned facet (the centre in the prism behind its triangle,
     * within depth of its plane), and those closing a gap between such cells: an unknown run of
     * at most depth cells each way along a grid axis, no free cell in it, behind cells at both
     * ends */
    RS_FS_KEEP_BEHIND = 1
} rs_fs_keep;

/* The occluders: first every unknown cell farther than depth (m, a city-block distance over the
 * grid) from every cell a facet of m lies in, or (RS_FS_KEEP_BEHIND) not behind a facet nor in a
 * gap between such cells, is taken as open (marked free, counted in fs->opened): unknown space
 * blocks only near what was scanned, the body behind a wall, the top of a slab, the back of a
 * pillar, not the open ground in a building's scan shadow. Then a mesh of the merged
 * known/unknown faces (two triangles per rectangle, wound to face the known side) and per
 * triangle the proxy facet of m: the nearest (by a breadth-first search over the grid from the
 * facets' cells) of the facets facing the face's way (normal within RS_FS_PROXY_COS of it), or of
 * every facet when none faces that way. *occ and *proxy are the caller's to free; *occ is NULL when there is no face.
 * -1 out of memory. */
int rs_freespace_occluders(rs_freespace *fs, const rs_mesh *m, double depth, rs_fs_keep keep, rs_mesh **occ,
                           uint32_t **proxy, rs_err *err);

#endif

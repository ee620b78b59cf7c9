/* texture_internal: what the texture stage's files share: the texel pages of the atlas, the
 * per-facet inputs, the raster of texels onto faces (texture_raster.c), the per-texel albedo
 * (texture.c) and the exports (texture_export.c). */
#ifndef RS_TEXTURE_INTERNAL_H
#define RS_TEXTURE_INTERNAL_H

#include <stddef.h>
#include <stdint.h>
#include "common/config.h"
#include "common/err.h"
#include "common/mesh.h"
#include "meshing/atlas.h"

/* Texel flags (channel "flags" of albedo_texture_flags.exr). */
#define RS_TEX_UNSEEN   1u /* no capture saw it: the facet's solved albedo */
#define RS_TEX_PENUMBRA 2u /* the sun's shadow edge crosses it: not resolved at this texel size */
#define RS_TEX_EDGE     4u /* just outside its face, on the face's plane (for filtering at edges) */
#define RS_TEX_GUTTER   8u /* filled by dilation: no surface */

/* The pages: texel k of page p is at index (p * side + y) * side + x. */
typedef struct {
    const rs_mesh *mesh;
    const rs_atlas *atlas;
    int side, npages;
    size_t ntex;
    int32_t *face;  /* the face a texel lies on, -1 none */
    float *rgb;     /* 3 per texel: albedo, linear */
    float *sigma;   /* relative standard uncertainty */
    uint8_t *flags; /* RS_TEX_* */
} rs_tex_pages;

int rs_tex_pages_alloc(rs_tex_pages *t, const rs_mesh *m, const rs_atlas *a);
void rs_tex_pages_free(rs_tex_pages *t);

/* Assigns every texel whose centre lies in a face to it (the first face of its chart in face
 * order when on a shared edge), then the texels next to those, outside the faces but inside the
 * chart's rectangle, to a neighbour's face (RS_TEX_EDGE). Returns the texels assigned. */
size_t rs_tex_raster(rs_tex_pages *t);

/* The point on face f of texel (x, y) of its page, clamped to the face, with its barycentrics. */
rs_v3 rs_tex_point(const rs_tex_pages *t, uint32_t f, int x, int y, double b[3]);

/* Fills every texel with no face from its faced neighbours, ring by ring (RS_TEX_GUTTER), so
 * that bilinear lookups and mipmaps near a chart's edge see its own colour; what no ring reaches
 * takes the page's mean. */
void rs_tex_dilate(rs_tex_pages *t);

/* The exports: albedo.glb, albedo.obj + albedo.mtl, albedo_vertex.ply, next to the texture
 * images (names[p]: page p's PNG file name). origin: rhoscan_origin (zero when none). */
typedef struct {
    const rs_config *cfg;
    const rs_tex_pages *pages;
    const char *const *png_names;
    double origin[3];
    size_t vertices; /* out: the split vertices written */
} rs_tex_export;

int rs_tex_export_all(rs_tex_export *e, rs_err *err);

/* What the ranks measured of the texels (the first pass: L and V) and the counts that go with
 * it. The counts are sums over texels, so adding the ranks' gives the single process's. */
#define RS_TEX_MAX_COUNTS 32
typedef struct {
    float *L;          /* 3 per texel */
    float *vis;        /* 1 per texel */
    uint8_t flag_mask; /* the pages' flags bits the measurement sets */
    int ncounts;       /* at most RS_TEX_MAX_COUNTS */
    uint64_t counts[RS_TEX_MAX_COUNTS];
} rs_tex_measured;

/* Collective (common/par.h): every rank measured the rows marked in mine (npages x side of
 * them, a row each rank took from the work queue); afterwards every rank holds every row's L, V
 * and measurement flags, and counts holds the sums over the ranks. A no-op on one rank. */
int rs_tex_share(rs_tex_pages *t, rs_tex_measured *m, const uint8_t *mine, rs_err *err);

/* Bilinear sample of the pages' albedo at (u, v) of page p (glTF's convention: v down),
 * clamped at the page's edge; into rgb. */
void rs_tex_sample(const rs_tex_pages *t, int p, double u, double v, float rgb[3]);

#endif

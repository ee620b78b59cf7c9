/* texture_share: the texel rows the MPI ranks measured, exchanged (texture_internal.h). A rank's
 * part is its counts, then per row it measured: the row's index and, for each of the row's
 * surface texels in order, L (3 floats), V (1 float) and its measurement flags (1 byte). Every
 * rank knows which texels are on a surface (the raster is replicated), so only those travel. */
#include <stdlib.h>
#include <string.h>
#include "common/par.h"
#include "stages/texture/texture_internal.h"

#define TEXEL_BYTES (4 * sizeof(float) + 1)

/* The surface texels of row r (a row of the pages' whole height, npages x side). */
static size_t row_texels(const rs_tex_pages *t, size_t r)
{
    size_t n = 0, S = (size_t)t->side;
    for (size_t x = 0; x < S; x++) n += t->face[r * S + x] >= 0;
    return n;
}

/* This rank's part, malloc'd into *out (*n its bytes); -1 when out of memory. */
static int pack_part(const rs_tex_pages *t, const rs_tex_measured *m, const uint8_t *mine, unsigned char **out,
                     size_t *n)
{
    size_t S = (size_t)t->side, rows = (size_t)t->npages * S, bytes = (size_t)m->ncounts * sizeof(uint64_t);
    for (size_t r = 0; r < rows; r++)
        if (mine[r]) bytes += sizeof(uint32_t) + row_texels(t, r) * TEXEL_BYTES;
    unsigned char *p = *out = malloc(bytes ? bytes : 1);
    if (!p) return -1;
    memcpy(p, m->counts, (size_t)m->ncounts * sizeof(uint64_t));
    p += (size_t)m->ncounts * sizeof(uint64_t);
    for (size_t r = 0; r < rows; r++) {
        if (!mine[r]) continue;
        uint32_t r32 = (uint32_t)r;
        memcpy(p, &r32, sizeof r32);
        p += sizeof r32;
        for (size_t k = r * S; k < (r + 1) * S; k++) {
            if (t->face[k] < 0) continue;
            memcpy(p, m->L + 3 * k, 3 * sizeof(float));
            memcpy(p + 3 * sizeof(float), m->vis + k, sizeof(float));
            p[4 * sizeof(float)] = t->flags[k] & m->flag_mask;
            p += TEXEL_BYTES;
        }
    }
    *n = bytes;
    return 0;
}

/* Another rank's part into the texels it measured; -1 when it is malformed. */
static int unpack_part(rs_tex_pages *t, rs_tex_measured *m, const unsigned char *p, size_t n, uint64_t *sums)
{
    size_t S = (size_t)t->side, rows = (size_t)t->npages * S, head = (size_t)m->ncounts * sizeof(uint64_t);
    if (n < head) return -1;
    for (int i = 0; i < m->ncounts; i++) {
        uint64_t c;
        memcpy(&c, p + i * sizeof c, sizeof c);
        sums[i] += c;
    }
    const unsigned char *end = p + n;
    p += head;
    while (p < end) {
        uint32_t r;
        if ((size_t)(end - p) < sizeof r) return -1;
        memcpy(&r, p, sizeof r);
        p += sizeof r;
        if (r >= rows || (size_t)(end - p) < row_texels(t, r) * TEXEL_BYTES) return -1;
        for (size_t k = (size_t)r * S; k < ((size_t)r + 1) * S; k++) {
            if (t->face[k] < 0) continue;
            memcpy(m->L + 3 * k, p, 3 * sizeof(float));
            memcpy(m->vis + k, p + 3 * sizeof(float), sizeof(float));
            t->flags[k] |= (uint8_t)(p[4 * sizeof(float)] & m->flag_mask);
            p += TEXEL_BYTES;
        }
    }
    return 0;
}

int rs_tex_share(rs_tex_pages *t, rs_tex_measured *m, const uint8_t *mine, rs_err *err)
{
    int size = rs_par_size();
    if (size <= 1) return 0;
    unsigned char *part = NULL, *all = NULL;
    size_t n = 0, total = 0, *starts = malloc(((size_t)size + 1) * sizeof *starts);
    uint64_t sums[RS_TEX_MAX_COUNTS] = {0};
    int failed = !starts || m->ncounts > RS_TEX_MAX_COUNTS || pack_part(t, m, mine, &part, &n) != 0;
    if (rs_par_any(failed)) {
        free(starts);
        free(part);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory for the texels' exchange between the ranks");
    }
    int rc = rs_par_allgather_bytes(part, n, &all, &total, starts, err);
    free(part);
    for (int r = 0; rc == 0 && r < size; r++) {
        if (r == rs_par_rank()) { /* its texels are in place: its counts only */
            for (int i = 0; i < m->ncounts; i++) sums[i] += m->counts[i];
            continue;
        }
        if (unpack_part(t, m, all + starts[r], starts[r + 1] - starts[r], sums) != 0)
            rc = rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "rank %d's texels arrived malformed", r);
    }
    if (rc == 0) memcpy(m->counts, sums, (size_t)m->ncounts * sizeof *sums);
    free(all);
    free(starts);
    return rc;
}

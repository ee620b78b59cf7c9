/* gather_share: the facets each rank gathered, sent to every rank (see gather_share.h). */
#include "light/gather_share.h"

#include <stdlib.h>
#include <string.h>
#include "common/par.h"

/* One facet on the wire: its position in the list, its gather (the entries pointer is
 * meaningless there), then its K row. */
typedef struct {
    uint64_t pos;
    rs_facet_gather fg;
} share_head;

static size_t record_bytes(const rs_facet_gather *f)
{
    return sizeof(share_head) + (size_t)f->nentries * sizeof(rs_kentry);
}

static rs_facet_gather *slot(const uint32_t *list, rs_facet_gather *fg, int by_position, size_t k)
{
    return &fg[by_position ? k : list[k]];
}

/* This rank's facets packed one after the other; NULL when out of memory. */
static unsigned char *pack_mine(const uint32_t *list, size_t n, rs_facet_gather *fg, int by_position,
                                const uint8_t *mine, size_t *bytes)
{
    size_t total = 0;
    for (size_t k = 0; k < n; k++)
        if (mine[k]) total += record_bytes(slot(list, fg, by_position, k));
    unsigned char *buf = malloc(total ? total : 1), *at = buf;
    if (!buf) return NULL;
    for (size_t k = 0; k < n; k++) {
        if (!mine[k]) continue;
        const rs_facet_gather *f = slot(list, fg, by_position, k);
        share_head h;
        memset(&h, 0, sizeof h); /* no stray padding bytes on the wire */
        h.pos = k;
        h.fg = *f;
        h.fg.entries = NULL;
        memcpy(at, &h, sizeof h);
        at += sizeof h;
        if (f->nentries) memcpy(at, f->entries, (size_t)f->nentries * sizeof(rs_kentry));
        at += (size_t)f->nentries * sizeof(rs_kentry);
    }
    *bytes = total;
    return buf;
}

int rs_gather_share(const uint32_t *list, size_t n, rs_facet_gather *fg, int by_position, const uint8_t *mine)
{
    if (rs_par_size() <= 1) return 0;
    size_t bytes = 0, total = 0;
    unsigned char *buf = pack_mine(list, n, fg, by_position, mine, &bytes), *all = NULL;
    size_t *starts = malloc(((size_t)rs_par_size() + 1) * sizeof *starts);
    rs_err err;
    rs_err_clear(&err);
    int failed = rs_par_any(!buf || !starts);
    if (!failed) failed = rs_par_allgather_bytes(buf, bytes, &all, &total, starts, &err) != 0;
    free(buf);
    int me = rs_par_rank();
    for (size_t at = 0; !failed && at < total;) {
        share_head h;
        memcpy(&h, all + at, sizeof h);
        size_t row = (size_t)h.fg.nentries * sizeof(rs_kentry);
        int own = at >= starts[me] && at < starts[me + 1];
        at += sizeof h;
        if (!own) {
            rs_facet_gather *f = slot(list, fg, by_position, (size_t)h.pos);
            *f = h.fg;
            f->entries = row ? malloc(row) : NULL;
            if (row && !f->entries) {
                f->nentries = 0;
                failed = 1;
                break;
            }
            if (row) memcpy(f->entries, all + at, row);
        }
        at += row;
    }
    free(all);
    free(starts);
    return rs_par_any(failed) ? -1 : 0;
}

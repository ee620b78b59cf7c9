/* kernel_out: streaming writer of transport.ply (see kernel_out.h). At 10^6 facets the kernel has
 * some 4e7 entries: copied into the PLY module's double columns it took 2.5 GB, streamed it takes nothing. */
#include "light/kernel_out.h"

#include "common/ply.h"

typedef struct {
    const rs_facet_gather *fg;
    size_t f;   /* facet of the next entry */
    uint32_t q; /* its index in the facet's row */
} kernel_cursor;

static int kernel_record(void *ctx, const rs_ply_element *el, size_t e, double *v, rs_err *err)
{
    (void)el, (void)e, (void)err;
    kernel_cursor *c = ctx;
    while (c->q >= c->fg[c->f].nentries) c->f++, c->q = 0; /* empty rows; the count is the rows' total */
    const rs_kentry *en = &c->fg[c->f].entries[c->q++];
    v[0] = (double)c->f;
    v[1] = en->col;
    v[2] = en->k;
    v[3] = en->k_unseen;
    return 0;
}

int rs_kernel_write(const char *path, const rs_facet_gather *fg, size_t nf, size_t *nentries, rs_err *err)
{
    size_t ne = 0;
    for (size_t f = 0; f < nf; f++) ne += fg[f].nentries;
    rs_ply *tp = rs_ply_new();
    rs_ply_element *tr = tp ? rs_ply_add_element(tp, "transport", ne) : NULL;
    if (!tr || !rs_ply_declare_scalar(tr, "row", RS_PLY_UINT32) || !rs_ply_declare_scalar(tr, "col", RS_PLY_UINT32) ||
        !rs_ply_declare_scalar(tr, "k", RS_PLY_FLOAT32) || !rs_ply_declare_scalar(tr, "k_unseen", RS_PLY_FLOAT32) ||
        rs_ply_add_comment(tp, "rhoscan %s sparse interreflection kernel: G_i = sum_j k L_j (k in sr)",
                           RHOSCAN_VERSION) != 0 ||
        rs_ply_add_comment(tp, "rhoscan_facets %zu", nf) != 0) {
        rs_ply_free(tp);
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory building transport.ply");
    }
    kernel_cursor cur = {fg, 0, 0};
    int rc = rs_ply_write_records(tp, path, 1, kernel_record, &cur, err);
    rs_ply_free(tp);
    if (rc == 0 && nentries) *nentries = ne;
    return rc;
}

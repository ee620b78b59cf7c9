/* kernel_out: transport.ply (the sparse K, see transport.h) written straight from the gather's
 * rows, one record at a time: no copy of the kernel, whatever its size. */
#ifndef RS_KERNEL_OUT_H
#define RS_KERNEL_OUT_H

#include <stddef.h>
#include "common/err.h"
#include "light/gather.h"

/* Writes fg[0..nf)'s rows as element 'transport' (row, col, k, k_unseen), binary, atomically;
 * *nentries (may be NULL) receives the entry count. */
int rs_kernel_write(const char *path, const rs_facet_gather *fg, size_t nf, size_t *nentries, rs_err *err);

#endif

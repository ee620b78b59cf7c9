/* select: the k-th smallest value of an array without sorting it (medians and percentiles of
 * per-pixel values over a whole panorama, where a sort was a large share of a stage). */
#ifndef RS_SELECT_H
#define RS_SELECT_H

#include <stddef.h>

/* The k-th smallest of v[0..n) (k < n, n > 0): the value a full sort puts at index k, by
 * Hoare's selection in expected linear time. v is reordered. */
float rs_select_kth(float *v, size_t n, size_t k);
double rs_select_kth_double(double *v, size_t n, size_t k);

#endif

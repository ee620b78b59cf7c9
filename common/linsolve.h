/* linsolve: small dense linear systems (plane and sky-model fits, reference solves in tests),
 * by Gaussian elimination with partial pivoting. Not for the kernel K: that is sparse. */
#ifndef RS_LINSOLVE_H
#define RS_LINSOLVE_H

#include <stddef.h>

/* Solves A x = b for n x n row-major A; A is overwritten and x replaces b. Returns -1 (A and b
 * then undefined) when a pivot falls below 1e-14 times A's largest entry: singular or nearly. */
int rs_solve_dense(double *A, double *b, size_t n);

#endif

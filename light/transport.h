/* transport: the sparse interreflection kernel K written by the irradiance stage
 * (transport.ply), in compressed-row form: G_i = sum_j K_ij L_j, K in steradians
 * (row sums <= pi). k_unseen is the part of K_ij whose hit points the camera did not see. */
#ifndef RS_TRANSPORT_H
#define RS_TRANSPORT_H

#include <stddef.h>
#include <stdint.h>
#include "common/err.h"

typedef struct rs_transport {
    size_t nfaces, nentries;
    size_t *row_start; /* nfaces + 1 */
    uint32_t *col;
    float *k, *k_unseen;
} rs_transport;

/* Reads and validates (indices in range, finite non-negative weights, rows in order). */
rs_transport *rs_transport_read(const char *path, size_t nfaces, rs_err *err);
void rs_transport_free(rs_transport *t);

/* Forward model L = L_s + diag(rho / pi) K L with L_s = rho E_sky / pi (3 channels interleaved),
 * by Jacobi iteration until the largest change relative to the largest radiance falls below tol.
 * Converges geometrically since row sums of K are <= pi and rho < 1. Writes L and G = K L;
 * returns the iterations used (-1: out of memory), *residual the last relative change. */
int rs_transport_solve(const rs_transport *K, const double *rho, const double *esky, double *L, double *G, double tol,
                       int max_iter, double *residual);

#endif

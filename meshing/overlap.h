/* overlap: one surface where several scans saw the same one. Each scan's grid mesh covers
 * the overlap with its own sheet, a few millimetres from the others (registration, noise):
 * left in, the sheets would shadow each other in every ray cast. */
#ifndef RS_OVERLAP_H
#define RS_OVERLAP_H

#include <stddef.h>
#include <stdint.h>
#include "common/cloud.h"
#include "common/err.h"
#include "common/mesh.h"

typedef struct rs_overlap_stats {
    size_t dropped;       /* faces dropped: another scan saw their surface better */
    size_t dropped_guess; /* of which guessed faces (nadir caps) covered by a real observation */
    size_t rays;
} rs_overlap_stats;

/* Marks drop[f] = 1 for every face f of scan owner[f] whose surface another scan t also
 * meshed (t's mesh, hit on the ray from t's scanner to f's centroid, lies within tol_m of
 * that centroid and faces the same way, normals within 45 degrees) and saw better: a smaller
 * footprint, range / cos(incidence) with the mean normal of the two faces, ties going to the
 * lower scan index. Faces with guess[f]
 * (nadir caps; guess may be NULL) lose to any observed face and never beat one. */
int rs_overlap_resolve(const rs_mesh *m, const int *owner, const uint8_t *guess, const rs_scan *scans, int nscans,
                       double tol_m, uint8_t *drop, rs_overlap_stats *st, rs_err *err);

/* After simplification, where the sheets of two scans met: a face with a face of another
 * connected sheet within tol_m along its normal, facing the same way, is dropped when it is
 * the smaller of the two (the seams of the kept regions overlap by up to a facet once the
 * simplifier straightens them). Unused vertices stay. */
int rs_overlap_dedup(rs_mesh *m, double tol_m, size_t *removed, rs_err *err);

#endif

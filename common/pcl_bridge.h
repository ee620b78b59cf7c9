/* pcl_bridge: the C face of the Point Cloud Library adapter (pcl_bridge.cpp, C++17): PCD
 * reading, outlier removal, voxel downsampling, normals and surface reconstruction. */
#ifndef RS_PCL_BRIDGE_H
#define RS_PCL_BRIDGE_H

#ifdef __cplusplus
extern "C" { /* around the includes too: err.h and cloud.h are C headers without guards */
#endif

#include <stddef.h>
#include <stdint.h>
#include "common/cloud.h"
#include "common/err.h"

/* Every function catches all C++ exceptions and reports them in err; PCL's own console
 * output is silenced. Coordinates are float (PCL's): callers recentre georeferenced clouds
 * first (rs_cloud_recentre). Results do not depend on the thread count. */

/* A PCD file (ascii, binary or binary_compressed) as an unorganized cloud: x y z (any
 * numeric type, double kept), intensity and rgb/rgba when present; NaN points are dropped.
 * Caller frees with rs_cloud_free. */
rs_cloud *rs_pcl_read_pcd(const char *path, rs_err *err);

/* Statistical outlier removal (Rusu et al. 2008): a point whose mean distance to its k nearest
 * neighbours exceeds the mean of that over all points by std_mul standard deviations gets
 * keep[i] = 0, the others keep[i] = 1. xyz holds 3 * n floats. */
int rs_pcl_outliers(const float *xyz, size_t n, int k, double std_mul, uint8_t *keep, rs_err *err);

/* For each of m query points, the mean distance to its k nearest neighbours among the n points
 * of xyz (itself, one of them, excluded: the first of k + 1), computed as rs_pcl_outliers does,
 * and the distance to the kth (the farthest of them). With fewer than k + 1 points, mean 0 and
 * kth INFINITY. The tiles of the ingest's streaming path use it. */
int rs_pcl_knn_mean(const float *xyz, size_t n, const float *query, size_t m, int k, float *mean, float *kth,
                    rs_err *err);

/* Voxel downsampling: one point per occupied cube of leaf_m, the centroid of its points;
 * intensity (may be NULL) and rgb (may be NULL) averaged the same way. Writes the new count
 * to *nout and new arrays to *xyz_out, *intensity_out, *rgb_out (NULL where the input was).
 * Fails with a clear message when the extent / leaf_m grid has more than 2^31 cells. */
int rs_pcl_voxel(const float *xyz, const float *intensity, const uint8_t *rgb, size_t n, double leaf_m, size_t *nout,
                 float **xyz_out, float **intensity_out, uint8_t **rgb_out, rs_err *err);

/* Normals from the k nearest neighbours (NormalEstimationOMP, threads 0 = all cores), each
 * turned toward its point's viewpoint (3 floats per point: the scanner that saw it).
 * Points with too few neighbours get a zero normal. */
int rs_pcl_normals(const float *xyz, size_t n, int k, const float *viewpoints, int threads, float *normals,
                   rs_err *err);

/* Greedy projection triangulation (Marton et al. 2009) of oriented points: triangles whose
 * edges are at most radius_m and at most mu times the local point spacing, indices into xyz.
 * Each triangle is wound counter-clockwise seen from the side its vertices' normals point to.
 * *tris (3 per triangle) is malloc'ed; caller frees. */
int rs_pcl_greedy(const float *xyz, const float *normals, size_t n, double radius_m, double mu, int max_nn,
                  uint32_t **tris, size_t *ntris, rs_err *err);

/* Screened Poisson reconstruction (Kazhdan et al.) of oriented points at octree depth; the
 * surface is new vertices (*verts, 3 floats each) and triangles. Caller frees both. */
int rs_pcl_poisson(const float *xyz, const float *normals, size_t n, int depth, float **verts, size_t *nverts,
                   uint32_t **tris, size_t *ntris, rs_err *err);

/* Distance from each of m query points to the nearest of the n cloud points (kd-tree); with
 * skip_self the queries are cloud points and the second nearest (not the point itself) counts. */
int rs_pcl_nearest(const float *xyz, size_t n, const float *query, size_t m, int skip_self, float *dist,
                   uint32_t *index, rs_err *err); /* index (the nearest point) may be NULL */

#ifdef __cplusplus
}
#endif

#endif

/* edge_pose: the calib stage's [capture] refine_edges step: the capture's pose (solved from pairs
 * or COLMAP, else [capture] position and rotation) refined by aligning the panorama's edges with
 * the model's (calib/edge_refine.h), into capture_pose.txt. */
#ifndef RS_EDGE_POSE_H
#define RS_EDGE_POSE_H

#include "common/config.h"
#include "common/err.h"
#include "pipeline/stage.h"

/* Does nothing (returns 0) unless [capture] refine_edges is true. Otherwise needs the work
 * folder's mesh.ply (the mesh stage) and the capture's panorama (stitched or [capture]
 * panorama); writes the refined pose and reports the costs, iterations and the pose change under
 * "edge_refinement". Errors name [capture] refine_edges: no mesh, no start position, too few
 * model or image edges to align. */
int rs_calib_edge_pose_run(const rs_config *cfg, rs_report *rep, rs_err *err);

#endif

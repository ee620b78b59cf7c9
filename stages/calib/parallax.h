/* parallax: what the calib stage's stitcher needs to correct the rig cameras' parallax: the
 * model (the mesh stage's mesh.ply) in a BVH and the rig's pose in the world ([rig] parallax). */
#ifndef RS_CALIB_PARALLAX_H
#define RS_CALIB_PARALLAX_H

#include "common/config.h"
#include "common/mesh.h"
#include "common/pano.h"
#include "common/scene.h"

typedef struct rs_parallax_model {
    rs_mesh *mesh;
    rs_scene *scene; /* NULL when the model is not used */
    rs_pose pose;    /* rig -> world */
    char why[256];   /* when not used: why not, for the report */
} rs_parallax_model;

/* 1 when [rig] parallax is on and the work folder has mesh.ply: the stitch can use the model
 * once the rig's pose is known. */
int rs_calib_parallax_wanted(const rs_config *cfg);

/* Loads the model and the pose: [capture] position and rotation, or, when the calib stage solves
 * the capture's pose (correspondences, colmap_panorama), the solved pose once pose_solved says it
 * has been written (before that the stale file of an earlier run must not be used). Returns 1
 * with m->scene set, 0 with m->why filled when the model is not used, -1 on error (unreadable
 * mesh, Embree). Release with rs_calib_parallax_release. */
int rs_calib_parallax_load(const rs_config *cfg, int pose_solved, rs_parallax_model *m, rs_err *err);
void rs_calib_parallax_release(rs_parallax_model *m);

#endif

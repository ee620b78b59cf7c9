/* stages: the stage functions, one per step of the pipeline, in order. Each reads its inputs
 * from the work folder and its config sections, and writes its outputs (see stage.h). */
#ifndef RS_STAGES_H
#define RS_STAGES_H

#include "stage.h"

int rs_ingest_run(const rs_config *cfg, rs_report *rep, rs_err *err);       /* -> cloud.ply */
int rs_mesh_run(const rs_config *cfg, rs_report *rep, rs_err *err);         /* -> mesh.ply */
int rs_calib_run(const rs_config *cfg, rs_report *rep, rs_err *err);       /* -> pano_stitched.exr, capture_pose.txt */
int rs_observe_run(const rs_config *cfg, rs_report *rep, rs_err *err);      /* -> observe.ply, facet_id.exr */
int rs_irradiance_run(const rs_config *cfg, rs_report *rep, rs_err *err);   /* -> irradiance.ply, transport.ply */
int rs_reflectance_run(const rs_config *cfg, rs_report *rep, rs_err *err);  /* -> albedo.ply */
int rs_render_run(const rs_config *cfg, rs_report *rep, rs_err *err);       /* -> images, render.json */

#endif

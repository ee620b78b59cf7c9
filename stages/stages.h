/* stages: the stage functions, one per step of the pipeline, in order. Each reads its inputs
 * from the work folder and its config sections, and writes its outputs (see stage.h). */
#ifndef RS_STAGES_H
#define RS_STAGES_H

#include "pipeline/stage.h"

int rs_ingest_run(const rs_config *cfg, rs_report *rep, rs_err *err);      /* -> cloud.ply */
int rs_mesh_run(const rs_config *cfg, rs_report *rep, rs_err *err);        /* -> mesh.ply */
int rs_calib_run(const rs_config *cfg, rs_report *rep, rs_err *err);       /* -> pano_stitched.exr, capture_pose.txt */
int rs_observe_run(const rs_config *cfg, rs_report *rep, rs_err *err);     /* -> observe.ply, facet_id.exr */
int rs_irradiance_run(const rs_config *cfg, rs_report *rep, rs_err *err);  /* -> irradiance.ply, transport.ply */
int rs_reflectance_run(const rs_config *cfg, rs_report *rep, rs_err *err); /* -> albedo.ply */
int rs_render_run(const rs_config *cfg, rs_report *rep, rs_err *err);      /* -> images, render.json */
int rs_texture_run(const rs_config *cfg, rs_report *rep, rs_err *err);     /* -> albedo texture, glb, obj, vertex ply */

/* Each stage's definition (stage.h: rs_stage_def). A stage program builds its own from these
 * and links only its own stage: the table below (stages.c) references every stage, so a
 * program that used it would load PCL, VTK and OpenCV at start (~0.3 s) whether it needs them
 * or not. */
#define RS_STAGE_DEF_INGEST                                                                \
    {                                                                                      \
        "ingest", rs_ingest_run, "ingest mesh", "", "cloud.ply",                           \
            "read laser scans (PTX, E57, PLY, PCD, XYZ text, LAS) into one point cloud", 0 \
    }
#define RS_STAGE_DEF_MESH                                                                              \
    {                                                                                                  \
        "mesh", rs_mesh_run, "mesh capture rig", "cloud.ply", "mesh.ply",                              \
            "triangulate the scan grids and simplify to the facet size (or take [mesh] input_mesh)", 0 \
    }
#define RS_STAGE_DEF_CALIB                                                                                   \
    {                                                                                                        \
        "calib", rs_calib_run, "calib rig capture colmap", "mesh.ply", "pano_stitched.exr capture_pose.txt", \
            "stitch the rig's frames into the capture's panorama; solve the capture's pose from pairs", 0    \
    }
#define RS_STAGE_DEF_OBSERVE                                                                                          \
    {                                                                                                                 \
        "observe", rs_observe_run, "observe capture rig", "mesh.ply pano_stitched.exr capture_pose.txt",              \
            "observe.ply facet_id.exr", "which facet each panorama pixel sees, and each facet's observed radiance", 1 \
    }
#define RS_STAGE_DEF_IRRADIANCE                                                                                     \
    {                                                                                                               \
        "irradiance", rs_irradiance_run, "irradiance capture sky rig",                                              \
            "mesh.ply observe.ply facet_id.exr pano_stitched.exr capture_pose.txt", "irradiance.ply transport.ply", \
            "sky irradiance and interreflection gather per facet", 1                                                \
    }
#define RS_STAGE_DEF_REFLECTANCE                                                            \
    {                                                                                       \
        "reflectance", rs_reflectance_run, "reflectance calib",                             \
            "mesh.ply observe.ply irradiance.ply transport.ply facet_id.exr", "albedo.ply", \
            "albedo per facet: interreflection, direct or paper", 0                         \
    }
#define RS_STAGE_DEF_RENDER                                                                                           \
    {                                                                                                                 \
        "render", rs_render_run, "render capture rig",                                                                \
            "albedo.ply transport.ply facet_id.exr pano_stitched.exr capture_pose.txt",                               \
            "irradiance.exr albedo.exr synth.exr diff.exr irradiance.png albedo.png synth.png diff.png observed.png", \
            "re-render the panorama from the albedo and compare with the observation", 1                              \
    }

/* The texture atlas's pages are albedo_texture.exr/.png with one page, albedo_texture_P.* with
 * several: only the files every run writes are listed. The sun's direction comes from
 * irradiance.json, which is not listed: its timings would make the recorded input hashes differ
 * from run to run, and it changes only with irradiance.ply (the same run writes both). */
#define RS_STAGE_DEF_TEXTURE                                                                           \
    {                                                                                                  \
        "texture", rs_texture_run, "texture capture rig",                                              \
            "albedo.ply irradiance.ply facet_id.exr pano_stitched.exr capture_pose.txt",               \
            "albedo.glb albedo.obj albedo.mtl albedo_vertex.ply",                                      \
            "per-texel albedo on a UV atlas; albedo.glb, albedo.obj, albedo_vertex.ply for viewers", 1 \
    }

/* Every stage in pipeline order, ended by {NULL} (stages.c): the driver's table. It references
 * every stage's code, so only the driver and the tests use it; a stage program passes its own
 * def. */
extern const rs_stage_def rs_stage_table[];
/* The stage of rs_stage_table called name, or NULL. */
const rs_stage_def *rs_stage_find(const char *name);

#endif

/* stages: the pipeline's stages in order, with what each reads and writes; the driver and
 * the rerun decisions are built on this table. */
#include "stages.h"

const rs_stage_def rs_stage_table[] = {
    {"ingest", rs_ingest_run, "ingest mesh", "", "cloud.ply",
     "read laser scans (PTX, PLY) into one point cloud"},
    {"mesh", rs_mesh_run, "mesh capture rig", "cloud.ply", "mesh.ply",
     "triangulate the scan grids and simplify to the facet size (or take [mesh] input_mesh)"},
    {"calib", rs_calib_run, "calib rig capture colmap", "mesh.ply", "pano_stitched.exr capture_pose.txt",
     "stitch the rig's frames into the capture's panorama; solve the capture's pose from pairs"},
    {"observe", rs_observe_run, "observe capture rig", "mesh.ply pano_stitched.exr capture_pose.txt",
     "observe.ply facet_id.exr",
     "which facet each panorama pixel sees, and each facet's observed radiance"},
    {"irradiance", rs_irradiance_run, "irradiance capture sky rig",
     "mesh.ply observe.ply facet_id.exr pano_stitched.exr capture_pose.txt",
     "irradiance.ply transport.ply", "sky irradiance and interreflection gather per facet"},
    {"reflectance", rs_reflectance_run, "reflectance calib",
     "mesh.ply observe.ply irradiance.ply transport.ply facet_id.exr",
     "albedo.ply", "albedo per facet: interreflection, direct or paper"},
    {"render", rs_render_run, "render capture rig",
     "albedo.ply transport.ply facet_id.exr pano_stitched.exr capture_pose.txt",
     "irradiance.exr albedo.exr synth.exr diff.exr irradiance.png albedo.png synth.png diff.png observed.png",
     "re-render the panorama from the albedo and compare with the observation"},
    {NULL, NULL, NULL, NULL, NULL, NULL}};

/* stages: the pipeline's stages in order, with what each reads and writes; the driver and
 * the rerun decisions are built on this table. */
#include "stages.h"

const rs_stage_def rs_stage_table[] = {
    {"ingest", rs_ingest_run, "ingest mesh", "", "cloud.ply",
     "read laser scans (PTX, PLY) into one point cloud"},
    {"mesh", rs_mesh_run, "mesh capture", "cloud.ply", "mesh.ply",
     "triangulate the scan grids and simplify to the facet size (or take [mesh] input_mesh)"},
    {"observe", rs_observe_run, "observe capture", "mesh.ply", "observe.ply facet_id.exr",
     "which facet each panorama pixel sees, and each facet's observed radiance"},
    {"irradiance", rs_irradiance_run, "irradiance capture sky", "mesh.ply observe.ply facet_id.exr",
     "irradiance.ply transport.ply", "sky irradiance and interreflection gather per facet"},
    {"reflectance", rs_reflectance_run, "reflectance", "mesh.ply observe.ply irradiance.ply transport.ply",
     "albedo.ply", "albedo per facet: interreflection, direct or paper"},
    {"render", rs_render_run, "render capture", "albedo.ply transport.ply facet_id.exr",
     "irradiance.exr albedo.exr synth.exr diff.exr irradiance.png albedo.png synth.png diff.png observed.png",
     "re-render the panorama from the albedo and compare with the observation"},
    {NULL, NULL, NULL, NULL, NULL, NULL}};

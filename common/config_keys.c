/* config_keys: the one table of every configuration key (configs/KEYS.md is generated from
 * the same facts). Angles in configs are in degrees where the key says _deg; code uses radians. */
#include "common/config.h"

#define INF 1e300

const rs_cfg_key rs_cfg_keys[] = {
    /* section, key, type, default, min, max, choices, unit, stages, help */
    {"pipeline", "workdir", RS_CFG_PATH, "out", 0, 0, NULL, "", "all", "output folder for every stage's files"},
    {"pipeline", "threads", RS_CFG_INT, "0", 0, 4096, NULL, "", "all",
     "worker threads (per MPI rank); 0 uses every core, shared out among the MPI ranks on the host (results "
     "do not depend on it)"},

    {"ingest", "scan", RS_CFG_PATHS, NULL, 0, 0, NULL, "", "ingest",
     "one or more point clouds: Leica PTX (organized), PLY, PCD, LAS 1.0-1.4, or XYZ/CSV text (.xyz .txt .csv .pts)"},
    {"ingest", "columns", RS_CFG_STRING, "x y z", 0, 0, NULL, "", "ingest",
     "XYZ/CSV text: what each column holds, in order: x y z intensity r g b nx ny nz, - to ignore one"},
    {"ingest", "scanner_position", RS_CFG_VEC3, NULL, 0, 0, NULL, "m", "ingest",
     "unorganized clouds: scanner centre in the world frame (normals are turned toward it); LAS without it: up"},
    {"ingest", "las_classes", RS_CFG_STRING, NULL, 0, 0, NULL, "", "ingest",
     "LAS: the class numbers to keep, space-separated (e.g. 2 6: ground and buildings); unset: every class"},
    {"ingest", "las_withheld", RS_CFG_ENUM, "drop", 0, 0, "drop|keep", "", "ingest",
     "LAS: points flagged withheld (not to be used, says the specification) are dropped, or kept"},
    {"ingest", "streaming", RS_CFG_BOOL, "true", 0, 0, NULL, "", "ingest",
     "LAS and unorganized E57: cloud.ply written from the reader's chunks, outlier removal and voxel grid in "
     "spatial tiles (memory independent of the cloud's size; same points); false: through the whole cloud"},
    {"ingest", "outlier_neighbours", RS_CFG_INT, "16", 0, 1000, NULL, "", "ingest",
     "unorganized points: statistical outlier removal over this many neighbours (PCL); 0 turns it off"},
    {"ingest", "outlier_std", RS_CFG_REAL, "3", 0.1, 100, NULL, "", "ingest",
     "a point goes when its mean neighbour distance exceeds the cloud's mean by this many standard deviations"},
    {"ingest", "voxel_size", RS_CFG_REAL, NULL, 1e-4, 100, NULL, "m", "ingest",
     "unorganized points: keep one point (the centroid) per cube of this size (PCL VoxelGrid); unset: off"},
    {"ingest", "recentre_above", RS_CFG_REAL, "10000", 1, 1e9, NULL, "m", "ingest",
     "coordinates beyond this are georeferenced: shift the cloud by whole metres (kept as rhoscan_origin)"},

    {"mesh", "input_mesh", RS_CFG_PATH, NULL, 0, 0, NULL, "", "ingest mesh",
     "a PLY triangle mesh that replaces ingest and meshing"},
    {"mesh", "facet_size", RS_CFG_REAL, NULL, 1e-4, 1e4, NULL, "m", "mesh",
     "target mean edge length; default from the panorama's pixel size at the model's distance"},
    {"mesh", "pixels_per_facet", RS_CFG_REAL, "6", 1, 1000, NULL, "px", "mesh",
     "with no facet_size: a facet spans about this many panorama pixels across"},
    {"mesh", "max_depth_ratio", RS_CFG_REAL, "0.05", 1e-4, 10, NULL, "", "mesh",
     "drop grid cells whose ranges differ by more than this fraction (depth discontinuity)"},
    {"mesh", "max_grazing_deg", RS_CFG_REAL, "85", 1, 90, NULL, "deg", "mesh",
     "drop grid triangles seen by the scanner at more than this angle from their normal"},
    {"mesh", "input_refine", RS_CFG_BOOL, "false", 0, 0, NULL, "", "mesh",
     "input_mesh: split its long edges down to the facet size a scan would get (facet_size, else from the panorama)"},
    {"mesh", "facets", RS_CFG_INT, NULL, 4, 100000000, NULL, "facets", "mesh",
     "simplify down to this many facets (with facet_size too: whichever comes first)"},

    {"mesh", "surface", RS_CFG_ENUM, "poisson", 0, 0, "poisson|greedy", "", "mesh",
     "unorganized clouds: Poisson reconstruction, or greedy projection triangulation (PCL; docs/BENCHMARKS.md)"},
    {"mesh", "normal_neighbours", RS_CFG_INT, "16", 3, 1000, NULL, "", "mesh",
     "unorganized clouds: neighbours of each point's normal estimate"},
    {"mesh", "max_edge", RS_CFG_REAL, NULL, 1e-4, 1e3, NULL, "m", "mesh",
     "unorganized clouds: longest triangle edge before simplification; default 8 x the 90th percentile spacing"},
    {"mesh", "poisson_depth", RS_CFG_INT, "10", 5, 14, NULL, "", "mesh", "surface = poisson: octree depth"},
    {"mesh", "overlap_tolerance", RS_CFG_REAL, "0.03", 1e-4, 10, NULL, "m", "mesh",
     "several scans: surfaces closer than this are one surface, kept from the scan that saw it best"},
    {"mesh", "report_points", RS_CFG_INT, "200000", 0, 100000000, NULL, "", "mesh",
     "scan points (evenly spread) whose distance to the mesh the report measures; 0: none"},

    {"mesh", "fill_nadir", RS_CFG_BOOL, "true", 0, 0, NULL, "", "mesh",
     "close the hole below each scanner with the plane of its lowest ring, when that ground is flat"},
    {"mesh", "nadir_max_rms", RS_CFG_REAL, "0.02", 0, 10, NULL, "m", "mesh",
     "the lowest ring must lie within this RMS distance of a plane for the nadir fill"},
    {"mesh", "denoise", RS_CFG_BOOL, "true", 0, 0, NULL, "", "mesh",
     "feature-preserving denoising of the simplified mesh: bilateral normal filter, then vertices follow the normals"},
    {"mesh", "denoise_iterations", RS_CFG_INT, "3", 1, 1000, NULL, "", "mesh",
     "denoise: passes of the bilateral filter over the face normals (faces sharing a vertex)"},
    {"mesh", "denoise_vertex_iterations", RS_CFG_INT, "10", 1, 1000, NULL, "", "mesh",
     "denoise: steps of the least-squares vertex update toward the filtered normals"},
    {"mesh", "denoise_sigma_r_deg", RS_CFG_REAL, "10", 0.1, 90, NULL, "deg", "mesh",
     "denoise: range sigma on the angle between normals; creases a few times larger are kept"},
    {"mesh", "denoise_sigma_s", RS_CFG_REAL, "1", 0.01, 100, NULL, "edges", "mesh",
     "denoise: spatial sigma on the distance between face centroids, in mean edge lengths"},
    {"mesh", "denoise_max_move", RS_CFG_REAL, "0.005", 1e-6, 10, NULL, "m", "mesh",
     "denoise: no vertex moves farther than this (a small multiple of the scan noise)"},

    {"capture", "panorama", RS_CFG_PATH, NULL, 0, 0, NULL, "", "mesh observe irradiance render texture",
     "equirectangular panorama (EXR or Radiance HDR), linear radiance, width = 2 x height; or an E57 file holding "
     "it as a spherical image with its pose (e57_image)"},
    {"capture", "e57_image", RS_CFG_STRING, NULL, 0, 0, NULL, "", "mesh observe irradiance render texture",
     "panorama = FILE.e57: the images2D entry that is the panorama, by name or 0-based index; unset: the file's only "
     "spherical image. Its pose is the capture's (position and rotation unused when it has one)"},
    {"capture", "response_file", RS_CFG_PATH, NULL, 0, 0, NULL, "", "mesh observe irradiance render texture",
     "panorama = FILE.e57: the camera response that linearises its 8-bit image (as [rig] response_file); unset: the "
     "sRGB curve, with a warning"},
    {"capture", "position", RS_CFG_VEC3, NULL, 0, 0, NULL, "m", "mesh observe irradiance render texture",
     "camera centre in the world frame (required: a forgotten pose would silently misplace every pixel)"},
    {"capture", "rotation", RS_CFG_ROTATION, "1 0 0 0 1 0 0 0 1", 0, 0, NULL, "",
     "mesh observe irradiance render texture", "camera local -> world rotation, 9 numbers row-major"},
    {"capture", "correspondences", RS_CFG_PATH, NULL, 0, 0, NULL, "", "calib observe irradiance render texture",
     "pairs file `column row X Y Z` per line (>= 4): the calib stage solves the pose; position and rotation only seed "
     "it"},
    {"capture", "colmap_panorama", RS_CFG_STRING, NULL, 0, 0, NULL, "", "calib observe irradiance render texture",
     "label of a panorama in the [colmap] views file: its views in the COLMAP model pose this capture (position, "
     "rotation unused)"},
    {"capture", "refine_edges", RS_CFG_BOOL, NULL, 0, 0, NULL, "", "calib observe irradiance render texture",
     "true: the calib stage refines the pose (solved, or position and rotation as a rough start) by aligning the "
     "panorama's edges with the model's (mesh.ply); unset or false: no refinement; [capture] only"},

    {"rig", "file", RS_CFG_PATH, NULL, 0, 0, NULL, "", "calib observe irradiance render texture",
     "camera rig in OpenCV FileStorage YAML (docs/DESIGN.md, section Rig file); its stitched panorama replaces "
     "[capture] panorama"},
    {"rig", "frames", RS_CFG_PATHS, NULL, 0, 0, NULL, "", "calib",
     "one image per rig camera, in the order of the rig file's cameras (EXR, HDR, PNG, JPEG, TIFF)"},
    {"rig", "exposure_times_s", RS_CFG_STRING, NULL, 0, 0, NULL, "s", "calib",
     "exposure brackets: times of each camera's 8-bit exposures (2 to 16, each > 0 and at most 3600 s); frames then "
     "lists them camera by camera (Debevec merge)"},
    {"rig", "response_file", RS_CFG_PATH, NULL, 0, 0, NULL, "", "calib",
     "with exposure_times_s (required): camera response, 256 lines (code 0..255) of 1 or 3 linear exposures from 1e-30 "
     "to 1e30, non-decreasing; replaces CalibrateDebevec"},
    {"rig", "width", RS_CFG_INT, "0", 0, 65536, NULL, "px", "calib",
     "stitched panorama width (height = width / 2); 0: from the finest camera's pixel angle"},
    {"rig", "feather_px", RS_CFG_REAL, "32", 0.5, 10000, NULL, "px", "calib",
     "blending weight ramps from 0 at a camera's usable border to 1 this many camera pixels inside"},
    {"rig", "gain", RS_CFG_BOOL, "true", 0, 0, NULL, "", "calib",
     "estimate one gain per camera from the overlaps (geometric mean 1) and apply it"},
    {"rig", "parallax", RS_CFG_BOOL, "true", 0, 0, NULL, "", "calib",
     "correct the cameras' parallax with the model's depth (mesh.ply, from the mesh stage) seen from the rig centre "
     "([capture] position, rotation or the solved pose); sky and false: infinite depth"},

    {"calib", "inlier_deg", RS_CFG_REAL, "0.5", 1e-4, 90, NULL, "deg", "calib",
     "registration: a pair is an inlier when the pose predicts its pixel within this angle"},
    {"calib", "ransac_iterations", RS_CFG_INT, "1000", 0, 10000000, NULL, "", "calib",
     "registration: random samples of 3 pairs tried before refinement"},
    {"calib", "seed", RS_CFG_INT, "1", 0, 2147483647, NULL, "", "calib", "registration: seed of the RANSAC samples"},
    {"calib", "edge_levels", RS_CFG_INT, "3", 1, 8, NULL, "", "calib",
     "edge refinement: pyramid levels, coarse to fine, each half the width of the next (more: a wider capture range)"},
    {"calib", "edge_max_width", RS_CFG_INT, "2048", 64, 65536, NULL, "px", "calib",
     "edge refinement: the finest level's width; the panorama is halved until it is at most this wide"},
    {"calib", "grey_card_region", RS_CFG_STRING, NULL, 0, 0, NULL, "px", "reflectance",
     "radiometric check: x0 y0 x1 y1, the capture panorama's pixels on a grey card (columns x0..x1-1, rows y0..y1-1; "
     "integers from 0 to 1048576, inside the panorama)"},
    {"calib", "grey_card_albedo", RS_CFG_REAL, "0.18", 0.001, 1, NULL, "", "reflectance",
     "the grey card's known albedo; reflectance.json reports pi L / (E_sky + G) over the region against it"},

    {"colmap", "model", RS_CFG_PATH, NULL, 0, 0, NULL, "", "calib",
     "folder of a COLMAP text model: cameras.txt, images.txt, points3D.txt (docs/COLMAP.md)"},
    {"colmap", "views", RS_CFG_PATH, NULL, 0, 0, NULL, "", "calib",
     "views file `NAME PANORAMA R00..R22 [TX TY TZ]`: which model images are views of which panorama, and their "
     "rotation"},
    {"colmap", "control_points", RS_CFG_PATH, NULL, 0, 0, NULL, "", "calib",
     "`image NAME X Y Z`, `point ID X Y Z` or `panorama LABEL X Y Z` per line (>= 3, not on one line; m): the "
     "similarity"},
    {"colmap", "max_rms_m", RS_CFG_REAL, "0.1", 0, 1e6, NULL, "m", "calib",
     "the alignment fails when the control points' RMS residual exceeds this"},

    {"observe", "min_pixels", RS_CFG_INT, "3", 1, 1000000, NULL, "px", "observe",
     "pure pixels (not on a facet border) needed to average a facet's radiance from pixels"},
    {"observe", "guard_px", RS_CFG_REAL, "0.75", 0, 4, NULL, "px", "observe",
     "a pixel counts as pure when rays this far from its centre (diagonally) hit the same facet"},
    {"observe", "facet_points", RS_CFG_INT, "16", 1, 4096, NULL, "", "observe",
     "points sampled on a facet too small for pixel averaging"},
    {"observe", "min_visible", RS_CFG_REAL, "0.5", 0.01, 1, NULL, "", "observe",
     "share of a small facet's points the camera must see for it to count as observed"},
    {"observe", "max_view_deg", RS_CFG_REAL, "84", 1, 89.9, NULL, "deg", "observe",
     "pixels that see a facet at more than this angle from its normal are not used"},

    {"irradiance", "samples", RS_CFG_INT, "256", 1, 1 << 20, NULL, "rays", "irradiance",
     "hemisphere rays per facet (explicit sun rays come on top)"},
    {"irradiance", "sky_samples", RS_CFG_INT, "512", 0, 1 << 16, NULL, "rays", "irradiance",
     "rays per facet drawn from the sky map's brightness, combined with the hemisphere rays (MIS)"},
    {"irradiance", "sun_samples", RS_CFG_INT, "64", 0, 1 << 16, NULL, "rays", "irradiance",
     "shadow rays per facet toward the bright sky pixels (0 turns explicit sun sampling off)"},
    {"irradiance", "sun_threshold", RS_CFG_REAL, "50", 1, 1e9, NULL, "", "irradiance",
     "sky pixels brighter than this multiple of the median sky radiance are sampled explicitly"},
    {"irradiance", "sun_max_cone_deg", RS_CFG_REAL, "3", 0.01, 90, NULL, "deg", "irradiance",
     "bright pixels are sampled explicitly up to the solid angle of a cone of this half-angle"},
    {"irradiance", "seed", RS_CFG_INT, "1", 0, 2147483647, NULL, "", "irradiance", "seed of the sample sequences"},
    {"irradiance", "skip_unseen", RS_CFG_BOOL, "true", 0, 0, NULL, "", "irradiance",
     "gather only the facets a camera sees and, transitively, those their rays hit (the rest light nothing seen)"},
    {"irradiance", "relay_share", RS_CFG_REAL, "0.125", 0.001, 1, NULL, "", "irradiance",
     "facets no camera sees, gathered because they light seen ones, trace this share of every ray count "
     "(rounded down to a power of two, at least one ray of each kind in use) and no adaptive rounds; 1: as seen ones"},
    {"irradiance", "sun_target_error", RS_CFG_REAL, "0", 0, 1, NULL, "", "irradiance",
     "> 0: double a facet's sun rays (up to 16 x sun_samples) until their standard error is below this share of E_sky"},
    {"irradiance", "target_error", RS_CFG_REAL, "0", 0, 1, NULL, "", "irradiance",
     "> 0: gather each facet in rounds, doubling all its ray counts (up to 16 x) until the standard error of its "
     "E_sky + G is below this share of it (sun_target_error is then unused); 0: the fixed counts"},
    {"irradiance", "skip_convex", RS_CFG_BOOL, "true", 0, 0, NULL, "", "irradiance",
     "facets with the whole model below their plane (bounding-box test) trace no ray: they see only sky"},
    {"irradiance", "sh_max_error", RS_CFG_REAL, "0.01", 0, 1, NULL, "", "irradiance",
     "those facets take E_sky from the sky map's order-2 harmonics, without rays, where the harmonics' relative "
     "error (measured on the map at 256 normals, 1.5 x the worst near the facet's) is below this (0: never)"},

    {"irradiance", "occluders", RS_CFG_ENUM, "freespace+planes", 0, 0, "off|freespace|planes|freespace+planes|file", "",
     "irradiance texture",
     "close the open scanned shell for the light: freespace builds a map of the space the scanners' and the camera's "
     "rays crossed and blocks every gather, sun and search ray that enters space none crossed (within the model's "
     "box grown by occluder_margin); planes closes the large planar regions where their geometry makes it certain "
     "(holes and edges in scan shadows filled in their plane, slabs seen only from below given their top); "
     "freespace+planes both; the faces go to occluders.ply; file takes them from occluders_file; off: rays that "
     "leave the mesh see the sky"},
    {"irradiance", "occluder_cell", RS_CFG_REAL, "0.25", 0.005, 100, NULL, "m", "irradiance",
     "edge of a free-space cell (grown until the grid has at most occluder_max_cells cells)"},
    {"irradiance", "occluder_margin", RS_CFG_REAL, "2", 0, 1000, NULL, "m", "irradiance",
     "the free-space grid covers the model's bounding box grown by this in x, y and downward (not upward): "
     "unknown space inside it blocks light, beyond it the sky is open"},
    {"irradiance", "occluder_depth", RS_CFG_REAL, "0.5", 0, 1000, NULL, "m", "irradiance",
     "unknown space blocks only within this distance of a scanned facet (the body behind a wall, the top of a slab, "
     "the back of a pillar); farther away it is taken as open (the ground in a building's scan shadow)"},
    {"irradiance", "occluder_keep", RS_CFG_ENUM, "behind", 0, 0, "behind|near", "", "irradiance",
     "which unknown cells within occluder_depth block: behind = those behind a scanned facet (along its inward "
     "normal) and those closing a gap between such cells; near = every one (also the air over unseen ground and "
     "the scan shadow beside a column, which fattens it)"},
    {"irradiance", "occluder_near", RS_CFG_REAL, "1.5", 0, 100, NULL, "cells", "irradiance",
     "occluder hits nearer than this many cells to a ray's origin are ignored, so that a facet is not shadowed "
     "by the unknown cells next to its own"},
    {"irradiance", "occluder_max_cells", RS_CFG_INT, "16777216", 4096, 268435456, NULL, "cells", "irradiance",
     "the free-space grid's largest cell count (2 bits each; the proxy search takes 8 bytes each while it runs)"},
    {"irradiance", "occluders_file", RS_CFG_PATH, NULL, 0, 0, NULL, "", "irradiance texture",
     "with occluders = file: a PLY of occluder faces (vertex x y z, face vertex_indices, int proxy: the mesh.ply "
     "facet whose radiance stands for the face's unseen surface), as occluders.ply is written"},

    {"sky", "panorama", RS_CFG_PATH, NULL, 0, 0, NULL, "", "irradiance",
     "sky-only panorama (EXR or HDR, linear) used for every direction it sees as sky"},
    {"sky", "position", RS_CFG_VEC3, NULL, 0, 0, NULL, "m", "irradiance",
     "sky panorama's centre in the world frame (required with panorama): its rays that hit the model are not sky"},
    {"sky", "rotation", RS_CFG_ROTATION, "1 0 0 0 1 0 0 0 1", 0, 0, NULL, "", "irradiance",
     "sky panorama's local -> world rotation, 9 numbers row-major"},
    {"sky", "fill", RS_CFG_ENUM, "model", 0, 0, "row|model", "", "irradiance",
     "directions no camera saw: model = Perez sky + harmonics, ground from the visible ground; row = interpolate along "
     "rows"},
    {"sky", "sun_azimuth_deg", RS_CFG_REAL, NULL, -360, 360, NULL, "deg", "irradiance",
     "world azimuth atan2(y, x) toward the sun (with sun_elevation_deg); default: from datetime or the image"},
    {"sky", "sun_elevation_deg", RS_CFG_REAL, NULL, -10, 90, NULL, "deg", "irradiance",
     "sun elevation above the horizon (with sun_azimuth_deg)"},
    {"sky", "datetime", RS_CFG_STRING, NULL, 0, 0, NULL, "", "irradiance",
     "capture time, ISO 8601 YYYY-MM-DDTHH:MM[:SS[.s]][Z|+HH:MM|-HH:MM] (a real calendar date, offset at most 14 h): "
     "sun from the NOAA solar position (needs latitude, longitude)"},
    {"sky", "latitude_deg", RS_CFG_REAL, NULL, -90, 90, NULL, "deg", "irradiance",
     "site latitude, north positive (with datetime)"},
    {"sky", "longitude_deg", RS_CFG_REAL, NULL, -180, 180, NULL, "deg", "irradiance",
     "site longitude, east positive (with datetime)"},
    {"sky", "north_deg", RS_CFG_REAL, "90", -360, 360, NULL, "deg", "irradiance",
     "world azimuth atan2(y, x) of geographic north (90: +Y is north)"},
    {"sky", "sun_irradiance", RS_CFG_REAL, NULL, 0, 1e12, NULL, "pano x sr", "irradiance",
     "clipped or hidden sun: its direct normal irradiance in the panorama's radiance unit x sr (W m^-2 for W m^-2 "
     "sr^-1), "
     "e.g. from a pyrheliometer; the disc leaves the sky map and each facet gets DNI max(0, n.s) V"},
    {"sky", "sun_color", RS_CFG_VEC3, "1 1 1", 0, 0, NULL, "", "irradiance",
     "with sun_irradiance: the sun's colour (linear RGB of the panorama, any scale, each >= 0); scaled to "
     "luminance 1, so that sun_irradiance stays the luminance of its DNI. A low sun is red"},
    {"sky", "sun_from_shadows", RS_CFG_ENUM, "auto", 0, 0, "auto|on|off", "", "irradiance",
     "a sun without sun_irradiance: its DNI and colour from the model's shadows (observed facets in full sun against "
     "ones in full shadow near them on the same plane). auto: when sun_azimuth_deg or datetime places it above the "
     "horizon where no camera saw sky or a bright pixel, and when nothing places it and no sky pixel is bright, its "
     "direction too, searched among those no camera saw for shadows that match the radiance; on: always (a clipped "
     "sun's disc leaves the panoramas); off: never"},
    {"sky", "sun_search_lead_sigmas", RS_CFG_REAL, "4", 0, 1000, NULL, "", "irradiance",
     "a searched sun (sun_from_shadows = auto, nothing places it) farther than 30 deg from where the visible sky's "
     "glow puts it is taken on evidence when its shadows' edge score beats the best direction within those 30 deg by "
     "at least this many standard errors (over blocks of facet pairs), it lights most of the paired facets whose "
     "albedo would otherwise exceed 1 and its DNI is significant; 0: never (only a direction near the glow)"},
    {"sky", "fill_from_facets", RS_CFG_ENUM, "auto", 0, 0, "auto|on|off", "", "irradiance",
     "the filled (hidden) sky's brightness from the observed facets that see it: same-plane pairs that see "
     "different shares of the fill's uncertain light fit one correction per channel, in units of that uncertainty "
     "(prior N(0, 1)), added to E_sky. auto: applied when it is at least 2 of its standard uncertainties; on: "
     "always when 50 pairs inform it; off: never"},
    {"sky", "fill_from_facets_modes", RS_CFG_ENUM, "directional", 0, 0, "directional|one", "", "irradiance",
     "with fill_from_facets: directional fits also a correction that varies with the filled direction "
     "(t0 + t1 x + t2 y of its world horizontal components, prior N(0, 1) each) and applies it in place of the one "
     "mode when its direction-dependent part is significant (chi-square on 2 degrees of freedom at least 6.18) and "
     "within range; one: the one mode alone"},
    {"sky", "sun_clip_level", RS_CFG_REAL, NULL, 0, 1e30, NULL, "pano", "irradiance",
     "with sun_irradiance: luminance from which sky pixels are the clipped disc; default 0.9 x the brightest near the "
     "sun"},
    {"sky", "sun_mask_deg", RS_CFG_REAL, "4", 0, 45, NULL, "deg", "irradiance",
     "model fill: sky within this angle of the sun is left out of the fit"},
    {"sky", "sh_order", RS_CFG_INT, "2", -1, 4, NULL, "", "irradiance",
     "model fill: highest spherical-harmonic order of the residual tried (held-out blocks pick the best)"},
    {"sky", "sh_ridge", RS_CFG_REAL, "0.001", 0, 1000, NULL, "", "irradiance",
     "model fill: ridge penalty of the residual harmonics, times (l (l + 1))^2"},
    {"sky", "ground_albedo", RS_CFG_REAL, "0.2", 0, 1, NULL, "", "irradiance",
     "model fill: the ground below the horizon that no camera saw near it is this albedo under the completed sky "
     "(with ground_albedo_from = scan, only when the scan's ground gives none)"},
    {"sky", "ground_albedo_from", RS_CFG_ENUM, "scan", 0, 0, "scan|config", "", "irradiance",
     "model fill: scan = that ground's albedo is the median of pi L / E over the scan's lowest level of observed "
     "upward facets that see only observed ones, each gathered first (not with an explicit sun, which comes after "
     "the gather: the measured ground is copied then); config = ground_albedo"},

    {"reflectance", "method", RS_CFG_ENUM, "interreflection", 0, 0, "interreflection|direct|paper", "", "reflectance",
     "interreflection: rho = pi L / (E_sky + G); direct: pi L / E_sky; paper: dense K"},
    {"reflectance", "min_irradiance", RS_CFG_REAL, "0.001", 0, 1, NULL, "", "reflectance",
     "facets whose irradiance is below this share of the median are not estimable"},
    {"reflectance", "albedo_sigma_floor", RS_CFG_REAL, "0.0025", 0, 1, NULL, "", "reflectance",
     "relative albedo uncertainty of what is not modelled (calibration, mesh); added in quadrature. Real captures: the "
     "grey card's relative deviation"},
    {"reflectance", "paper_max_facets", RS_CFG_INT, "4000", 1, 100000, NULL, "facets", "reflectance",
     "refuse method = paper above this facet count (O(m^3) visibility)"},
    {"reflectance", "pool_accuracy", RS_CFG_REAL, "0.1", 0, 0.5, NULL, "", "reflectance",
     "Ward's ambient accuracy: facets of one plane within this share of their harmonic mean distance to what they see "
     "(and within about 32 facets' area) share the sky and interreflection part of their irradiance, not the sun's: "
     "less sampling noise at a bias of that order; 0 = each facet its own gather; not with method = paper"},
    {"reflectance", "albedo_pool_sigmas", RS_CFG_REAL, "3", 0, 10, NULL, "sigma", "reflectance",
     "> 0: each estimable facet's albedo is pooled with its same-plane neighbours (within about 32 facets' area) whose "
     "albedo agrees with its own within this many combined standard errors in every channel (a larger step is an "
     "edge and stays), weighted by inverse variance and shrunk toward their mean by how much of their scatter the "
     "noise explains (a resolved texture stays); 0 = each facet its own albedo; not with method = paper"},
    {"reflectance", "unobserved_albedo", RS_CFG_REAL, NULL, 0, 1, NULL, "", "reflectance",
     "albedo assumed for facets the camera does not see; default: see unobserved_albedo_by"},
    {"reflectance", "unobserved_albedo_by", RS_CFG_ENUM, "orientation", 0, 0, "orientation|all", "", "reflectance",
     "with no unobserved_albedo: orientation = the area-weighted mean albedo of the estimable facets facing the same "
     "way (normal within 45 degrees of up, of down, or between), shrunk toward all's by 1 % of their area; all = "
     "one mean of all"},

    {"render", "tolerance", RS_CFG_REAL, "1e-6", 1e-12, 0.1, NULL, "", "render",
     "forward solve stops when the largest relative change falls below this"},
    {"render", "max_iterations", RS_CFG_INT, "10000", 1, 10000000, NULL, "", "render", "forward solve iteration limit"},
    {"render", "exposure", RS_CFG_REAL, NULL, 1e-12, 1e12, NULL, "", "render",
     "scale of the radiance PNG previews; default maps the 99th percentile to 1"},

    {"report", "write", RS_CFG_BOOL, "true", 0, 0, NULL, "", "report",
     "rebuild WORKDIR/report.html (and its images in WORKDIR/report/) after every stage run; rhoscan report WORKDIR "
     "rebuilds it on demand"},
    {"report", "truth", RS_CFG_PATH, NULL, 0, 0, NULL, "", "report",
     "a truth PLY (float red green blue albedo and an integer part per face, as a reference scene's truth.ply): the "
     "report adds the per-part albedo error table and the error map"},
    {"texture", "texel_size", RS_CFG_REAL, NULL, 1e-4, 100, NULL, "m", "texture",
     "texel side on the surface; default: the finest panorama sampling on the model (10th percentile over the "
     "observed facets of a pixel's footprint), raised to stay within max_texels"},
    {"texture", "max_texels", RS_CFG_INT, "16777216", 4096, 1073741824, NULL, "texels", "texture",
     "the atlas pages' texels, all pages together, at most this many (about 21 bytes each while the stage runs)"},
    {"texture", "chart_angle_deg", RS_CFG_REAL, "10", 0.1, 60, NULL, "deg", "texture",
     "connected facets whose normals lie within this of a chart's first facet share its chart"},
    {"texture", "gutter", RS_CFG_INT, "4", 1, 64, NULL, "texels", "texture",
     "empty texels around each chart, filled by dilation so that mipmaps show no seams"},
    {"texture", "max_side", RS_CFG_INT, "8192", 64, 8192, NULL, "texels", "texture",
     "largest atlas page side (a power of two); more pages when one is not enough"},
    {"texture", "filter", RS_CFG_ENUM, "bilinear", 0, 0, "bilinear|area", "", "texture",
     "how a texel samples the panorama: bilinear (n x n bilinear lookups, n = texel / pixel footprint, 1 to 3) or "
     "area (the mean over the texel of the pixels read as constant squares: a step between two pixels stays "
     "within a texel's width, at the cost of pixel-sized blocks where the texel is finer than a pixel)"},

    {NULL, NULL, 0, NULL, 0, 0, NULL, NULL, NULL, NULL}};

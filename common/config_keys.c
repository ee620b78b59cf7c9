/* config_keys: the one table of every configuration key (configs/KEYS.md is generated from
 * the same facts). Angles in configs are in degrees where the key says _deg; code uses radians. */
#include "config.h"

#define INF 1e300

const rs_cfg_key rs_cfg_keys[] = {
    /* section, key, type, default, min, max, choices, unit, stages, help */
    {"pipeline", "workdir", RS_CFG_PATH, "out", 0, 0, NULL, "", "all",
     "output folder for every stage's files"},
    {"pipeline", "threads", RS_CFG_INT, "0", 0, 4096, NULL, "", "all",
     "worker threads; 0 uses every core (results do not depend on it)"},

    {"ingest", "scan", RS_CFG_PATHS, NULL, 0, 0, NULL, "", "ingest",
     "one or more point clouds: Leica PTX (organized) or PLY"},

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
    {"mesh", "facets", RS_CFG_INT, NULL, 4, 100000000, NULL, "facets", "mesh",
     "simplify down to this many facets (with facet_size too: whichever comes first)"},

    {"mesh", "fill_nadir", RS_CFG_BOOL, "true", 0, 0, NULL, "", "mesh",
     "close the hole below each scanner with the plane of its lowest ring, when that ground is flat"},
    {"mesh", "nadir_max_rms", RS_CFG_REAL, "0.02", 0, 10, NULL, "m", "mesh",
     "the lowest ring must lie within this RMS distance of a plane for the nadir fill"},

    {"capture", "panorama", RS_CFG_PATH, NULL, 0, 0, NULL, "", "mesh observe irradiance render",
     "equirectangular panorama (EXR or Radiance HDR), linear radiance, width = 2 x height"},
    {"capture", "position", RS_CFG_VEC3, NULL, 0, 0, NULL, "m", "mesh observe irradiance render",
     "camera centre in the world frame (required: a forgotten pose would silently misplace every pixel)"},
    {"capture", "rotation", RS_CFG_ROTATION, "1 0 0 0 1 0 0 0 1", 0, 0, NULL, "", "mesh observe irradiance render",
     "camera local -> world rotation, 9 numbers row-major"},

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
    {"irradiance", "seed", RS_CFG_INT, "1", 0, 2147483647, NULL, "", "irradiance",
     "seed of the sample sequences"},
    {"irradiance", "skip_unseen", RS_CFG_BOOL, "true", 0, 0, NULL, "", "irradiance",
     "gather only the facets a camera sees and, transitively, those their rays hit (the rest light nothing seen)"},
    {"irradiance", "sun_target_error", RS_CFG_REAL, "0", 0, 1, NULL, "", "irradiance",
     "> 0: double a facet's sun rays (up to 16 x sun_samples) until their standard error is below this share of E_sky"},
    {"irradiance", "skip_convex", RS_CFG_BOOL, "true", 0, 0, NULL, "", "irradiance",
     "facets with the whole model below their plane (bounding-box test) trace no ray: they see only sky"},

    {"reflectance", "method", RS_CFG_ENUM, "interreflection", 0, 0, "interreflection|direct|paper", "",
     "reflectance", "interreflection: rho = pi L / (E_sky + G); direct: pi L / E_sky; paper: dense K"},
    {"reflectance", "min_irradiance", RS_CFG_REAL, "0.001", 0, 1, NULL, "", "reflectance",
     "facets whose irradiance is below this share of the median are not estimable"},
    {"reflectance", "paper_max_facets", RS_CFG_INT, "4000", 1, 100000, NULL, "facets", "reflectance",
     "refuse method = paper above this facet count (O(m^3) visibility)"},
    {"reflectance", "unobserved_albedo", RS_CFG_REAL, NULL, 0, 1, NULL, "", "reflectance",
     "albedo assumed for facets the camera does not see; default: the observed area-weighted mean"},

    {"render", "tolerance", RS_CFG_REAL, "1e-6", 1e-12, 0.1, NULL, "", "render",
     "forward solve stops when the largest relative change falls below this"},
    {"render", "max_iterations", RS_CFG_INT, "10000", 1, 10000000, NULL, "", "render",
     "forward solve iteration limit"},
    {"render", "exposure", RS_CFG_REAL, NULL, 1e-12, 1e12, NULL, "", "render",
     "scale of the radiance PNG previews; default maps the 99th percentile to 1"},

    {NULL, NULL, 0, NULL, 0, 0, NULL, NULL, NULL, NULL}};

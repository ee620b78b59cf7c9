/* freespace_bench: the cost of the free-space map and its occluders ([irradiance] occluders,
 * meshing/freespace.h) on the bench's procedural city (scenegen.h): grid set-up, carving R rays
 * (a scanner's returns and a camera's sky, traced on the mesh from the city's street camera),
 * the occluder faces, and what the occluders add to tracing rays that leave the mesh.
 * usage: rhoscan-freespace-bench FACETS RAYS [CELL_M]   (docs/BENCHMARKS.md, "Free-space map")
 *        rhoscan-freespace-bench --libs FACETS RAYS [CELL_M]: the same rays carved into the grid and
 *        into OctoMap's and OpenVDB's maps (those installed when it was built), one thread each. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include "bench/scenegen.h"
#include "common/log.h"
#include "common/sampling.h"
#include "common/scene.h"
#include "meshing/freespace.h"
#include "bench/freespace_libs.h"

static double peak_mb(void)
{
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return ru.ru_maxrss / 1024.0;
}

/* n rays from o in Sobol directions over the sphere: the first n / 2 traced on the mesh and carved
 * to their hits (a scanner's returns), the rest carved to the grid's edge when they escape (a
 * camera's sky) or to their hits. */
static void carve(rs_freespace *fs, const rs_scene *sc, rs_v3 o, size_t n)
{
#pragma omp parallel for schedule(dynamic, 1)
    for (long b = 0; b < (long)((n + 1023) / 1024); b++) {
        rs_ray rays[1024];
        rs_hit hits[1024];
        size_t k0 = (size_t)b * 1024, m = n - k0 < 1024 ? n - k0 : 1024;
        for (size_t i = 0; i < m; i++) {
            double x, y;
            rs_sobol2_owen((uint32_t)(k0 + i), 17, &x, &y);
            double z = 1 - 2 * x, r = sqrt(fmax(0, 1 - z * z)), phi = 2 * M_PI * y;
            rays[i] = (rs_ray){o, rs_v3_make(r * cos(phi), r * sin(phi), z), 0, INFINITY};
        }
        rs_scene_intersect(sc, rays, hits, m);
        for (size_t i = 0; i < m; i++) {
            if (hits[i].face != RS_NO_HIT)
                rs_freespace_carve(fs, o, rs_v3_add(o, rs_v3_scale(rays[i].dir, hits[i].t)), 0);
            else if (k0 + i >= n / 2)
                rs_freespace_carve(fs, o, rs_v3_add(o, rays[i].dir), 1);
        }
    }
}

/* Seconds to trace n cosine-like rays upward from the facets' centroids (the gather's escapes). */
static double trace_time(const rs_scene *sc, const rs_mesh *m, size_t n, size_t *escaped)
{
    double t0 = rs_now();
    size_t esc = 0;
#pragma omp parallel for schedule(dynamic, 1) reduction(+ : esc)
    for (long b = 0; b < (long)((n + 1023) / 1024); b++) {
        rs_ray rays[1024];
        rs_hit hits[1024];
        size_t k0 = (size_t)b * 1024, cnt = n - k0 < 1024 ? n - k0 : 1024;
        for (size_t i = 0; i < cnt; i++) {
            size_t f = ((k0 + i) * 2654435761u) % m->nfaces;
            rs_v3 c, nrm;
            double a, x, y;
            rs_mesh_face(m, f, &c, &nrm, &a);
            rs_sobol2_owen((uint32_t)(k0 + i), 5, &x, &y);
            rs_v3 d = rs_cosine_hemisphere(nrm, x, y);
            rays[i] = (rs_ray){rs_v3_add(c, rs_v3_scale(nrm, 1e-3)), d, 0, INFINITY};
        }
        rs_scene_intersect(sc, rays, hits, cnt);
        for (size_t i = 0; i < cnt; i++) esc += hits[i].face == RS_NO_HIT;
    }
    *escaped = esc;
    return rs_now() - t0;
}

#if defined(RS_HAVE_OCTOMAP) || defined(RS_HAVE_OPENVDB)
typedef struct carve_seg {
    rs_v3 a, b;
    int to_edge;
} carve_seg;

/* One library's map behind the same five calls. */
typedef struct free_map_lib {
    const char *name;
    void *(*make)(const rs_freespace *fs);
    void (*carve)(void *map, const double a[3], const double b[3], int hit);
    int (*state)(const void *map, const double p[3]);
    void (*finish)(void *map); /* after the last carve, or NULL */
    size_t (*bytes)(const void *map);
    void (*release)(void *map);
} free_map_lib;

#ifdef RS_HAVE_OCTOMAP
static void *octo_make(const rs_freespace *fs)
{
    return rs_octo_new(fs->cell);
}
static void octo_carve(void *m, const double a[3], const double b[3], int hit)
{
    rs_octo_carve(m, a, b, hit);
}
static int octo_state(const void *m, const double p[3])
{
    return rs_octo_state(m, p);
}
static void octo_finish(void *m)
{
    rs_octo_finish(m);
}
static size_t octo_bytes(const void *m)
{
    return rs_octo_bytes(m);
}
static void octo_release(void *m)
{
    rs_octo_free(m);
}
#endif
#ifdef RS_HAVE_OPENVDB
static void *vdb_make(const rs_freespace *fs)
{
    return rs_vdb_new(fs->cell, fs->lo);
}
static void vdb_carve(void *m, const double a[3], const double b[3], int hit)
{
    rs_vdb_carve(m, a, b, hit);
}
static int vdb_state(const void *m, const double p[3])
{
    return rs_vdb_state(m, p);
}
static size_t vdb_bytes(const void *m)
{
    return rs_vdb_bytes(m);
}
static void vdb_release(void *m)
{
    rs_vdb_free(m);
}
#endif

static const free_map_lib free_map_libs[] = {
#ifdef RS_HAVE_OCTOMAP
    {"OctoMap", octo_make, octo_carve, octo_state, octo_finish, octo_bytes, octo_release},
#endif
#ifdef RS_HAVE_OPENVDB
    {"OpenVDB", vdb_make, vdb_carve, vdb_state, NULL, vdb_bytes, vdb_release},
#endif
};

/* The point where the ray a + t d (t > 0) leaves the grid's box: the libraries carve segments, so
 * a ray that saw sky is carved to the same edge as rs_freespace_carve's to_edge. */
static rs_v3 box_exit(const rs_freespace *fs, rs_v3 a, rs_v3 d)
{
    double t = INFINITY, p[3] = {a.x, a.y, a.z}, v[3] = {d.x, d.y, d.z};
    for (int k = 0; k < 3; k++) {
        double hi = fs->lo[k] + fs->n[k] * fs->cell;
        if (v[k] > 0) t = fmin(t, (hi - p[k]) / v[k]);
        if (v[k] < 0) t = fmin(t, (fs->lo[k] - p[k]) / v[k]);
    }
    return rs_v3_add(a, rs_v3_scale(d, fmax(t, 0)));
}

/* carve()'s rays traced once into segments. */
static carve_seg *trace_segments(const rs_bench_scene *bs, const rs_scene *sc, const rs_freespace *fs, size_t n,
                                 size_t *ns)
{
    carve_seg *seg = malloc(n * sizeof *seg);
    if (!seg) return NULL;
    *ns = 0;
    for (size_t k0 = 0; k0 < n; k0 += 1024) {
        rs_ray rays[1024];
        rs_hit hits[1024];
        size_t m = n - k0 < 1024 ? n - k0 : 1024;
        for (size_t i = 0; i < m; i++) {
            double x, y;
            rs_sobol2_owen((uint32_t)(k0 + i), 17, &x, &y);
            double z = 1 - 2 * x, r = sqrt(fmax(0, 1 - z * z)), phi = 2 * M_PI * y;
            rays[i] = (rs_ray){bs->camera, rs_v3_make(r * cos(phi), r * sin(phi), z), 0, INFINITY};
        }
        rs_scene_intersect(sc, rays, hits, m);
        for (size_t i = 0; i < m; i++) {
            if (hits[i].face != RS_NO_HIT)
                seg[(*ns)++] = (carve_seg){bs->camera, rs_v3_add(bs->camera, rs_v3_scale(rays[i].dir, hits[i].t)), 0};
            else if (k0 + i >= n / 2)
                seg[(*ns)++] = (carve_seg){bs->camera, box_exit(fs, bs->camera, rays[i].dir), 1};
        }
    }
    return seg;
}

/* The comparison: the same segments carved into the grid and into each library's map at the grid's
 * cell size, each on one thread, then every grid cell's centre asked of both. */
static int compare_libs(const rs_bench_scene *bs, const rs_scene *sc, rs_freespace *fs, size_t n)
{
    size_t ns;
    carve_seg *seg = trace_segments(bs, sc, fs, n, &ns);
    if (!seg) return 2;
    double t0 = rs_now();
    for (size_t i = 0; i < ns; i++) rs_freespace_carve(fs, seg[i].a, seg[i].b, seg[i].to_edge);
    printf("segments %zu, one thread each | grid: %.2f s (%.2f Msegments/s), %.1f MB\n", ns, rs_now() - t0,
           ns / 1e6 / (rs_now() - t0), fs->ncells / 4 / 1048576.0);
    for (size_t l = 0; l < sizeof free_map_libs / sizeof free_map_libs[0]; l++) {
        const free_map_lib *lib = &free_map_libs[l];
        void *map = lib->make(fs);
        if (!map) return 2;
        double rss0 = peak_mb(), t1 = rs_now();
        for (size_t i = 0; i < ns; i++)
            lib->carve(map, (double[3]){seg[i].a.x, seg[i].a.y, seg[i].a.z},
                       (double[3]){seg[i].b.x, seg[i].b.y, seg[i].b.z}, !seg[i].to_edge);
        if (lib->finish) lib->finish(map);
        double t2 = rs_now();
        size_t grid_free = 0, lib_free = 0, both = 0;
        for (int k = 0; k < fs->n[2]; k++)
            for (int j = 0; j < fs->n[1]; j++)
                for (int i = 0; i < fs->n[0]; i++) {
                    double p[3] = {fs->lo[0] + (i + 0.5) * fs->cell, fs->lo[1] + (j + 0.5) * fs->cell,
                                   fs->lo[2] + (k + 0.5) * fs->cell};
                    int g = rs_freespace_cell(fs, i, j, k) & RS_FS_FREE, o = lib->state(map, p) == RS_FS_FREE;
                    grid_free += g, lib_free += o, both += g && o;
                }
        printf("  %s: %.2f s (%.2f Msegments/s), %.1f MB (peak RSS +%.0f MB) | cells free: grid %zu, %s %zu, both "
               "%zu\n",
               lib->name, t2 - t1, ns / 1e6 / (t2 - t1), lib->bytes(map) / 1048576.0, peak_mb() - rss0, grid_free,
               lib->name, lib_free, both);
        lib->release(map);
    }
    free(seg);
    return 0;
}
#endif

int main(int argc, char **argv)
{
    int libs = argc > 1 && strcmp(argv[1], "--libs") == 0;
    if (libs) argc--, argv++;
    if (argc < 3) {
        fprintf(stderr, "usage: %s FACETS RAYS [CELL_M]\n", argv[0]);
        return 1;
    }
    size_t facets = strtoull(argv[1], NULL, 10), nrays = strtoull(argv[2], NULL, 10);
    double cell = argc > 3 ? atof(argv[3]) : 0.25;
    rs_bench_scene *bs = rs_bench_scene_new(facets, 1);
    if (!bs) return 2;
    rs_err err;
    rs_scene *sc = rs_scene_new(bs->mesh, &err);
    if (!sc) return 2;
    double base_mb = peak_mb(), t0 = rs_now();
    rs_freespace fs;
    rs_freespace_opts fo = {.cell = cell, .margin = 2, .max_cells = 16777216};
    if (rs_freespace_init(&fs, bs->mesh, &fo, &err) != 0) return 2;
    if (libs) {
#if defined(RS_HAVE_OCTOMAP) || defined(RS_HAVE_OPENVDB)
        int rc = compare_libs(bs, sc, &fs, nrays);
#else
        fprintf(stderr,
                "%s: built without OctoMap or OpenVDB (install liboctomap-dev or libopenvdb-dev and "
                "configure again)\n",
                argv[0]);
        int rc = 1;
#endif
        rs_freespace_release(&fs);
        rs_scene_free(sc);
        rs_bench_scene_free(bs);
        return rc;
    }
    double t1 = rs_now();
    carve(&fs, sc, bs->camera, nrays);
    double t2 = rs_now();
    rs_mesh *occ;
    uint32_t *proxy;
    if (rs_freespace_occluders(&fs, bs->mesh, 0.5, RS_FS_KEEP_BEHIND, &occ, &proxy, &err) != 0) return 2;
    double t3 = rs_now();
    size_t trays = 2000000, esc0, esc1;
    double plain = trace_time(sc, bs->mesh, trays, &esc0);
    if (occ && rs_scene_set_occluders(sc, occ, proxy, 1.5 * fs.cell, &err) != 0) return 2;
    double with = trace_time(sc, bs->mesh, trays, &esc1);
    printf("facets %zu grid %d x %d x %d (%.3g m, %.1f MB) rays %zu | init %.2f s carve %.2f s (%.2f Mrays/s) "
           "faces %.2f s -> %zu occluder triangles | peak RSS %.0f MB (+%.0f over the scene) | 2e6 gather rays: %.2f s "
           "plain, %.2f s with occluders, escaped %zu -> %zu\n",
           bs->mesh->nfaces, fs.n[0], fs.n[1], fs.n[2], fs.cell, fs.ncells / 4 / 1048576.0, nrays, t1 - t0, t2 - t1,
           nrays / 1e6 / (t2 - t1), t3 - t2, occ ? occ->nfaces : 0, peak_mb(), peak_mb() - base_mb, plain, with, esc0,
           esc1);
    rs_scene_free(sc);
    rs_mesh_free(occ);
    free(proxy);
    rs_freespace_release(&fs);
    rs_bench_scene_free(bs);
    return 0;
}

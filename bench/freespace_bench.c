/* freespace_bench: the cost of the free-space map and its occluders ([irradiance] occluders,
 * meshing/freespace.h) on the bench's procedural city (scenegen.h): grid set-up, carving R rays
 * (a scanner's returns and a camera's sky, traced on the mesh from the city's street camera),
 * the occluder faces, and what the occluders add to tracing rays that leave the mesh.
 * usage: rhoscan-freespace-bench FACETS RAYS [CELL_M]   (docs/BENCHMARKS.md, "Free-space map") */
#include <stdio.h>
#include <stdlib.h>
#include <sys/resource.h>
#include "bench/scenegen.h"
#include "common/log.h"
#include "common/sampling.h"
#include "common/scene.h"
#include "meshing/freespace.h"

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

int main(int argc, char **argv)
{
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

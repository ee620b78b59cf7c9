/* facet_bytes: what one facet of a mesh costs in memory in the irradiance stage's replicated
 * state, for the cluster plan (docs/BENCHMARKS.md, "Memory per facet"). Reads MESH.ply into an
 * rs_mesh and builds Embree's BVH over it as common/scene.c does (the same build quality and
 * buffers, on a device of its own so that its allocations can be counted), then prints one line
 * per part: bytes in all and per facet.
 *   - the mesh: rs_mesh's float vertices and uint32 corners (exact, from the counts);
 *   - the scene's face normals (3 floats a face, common/scene.c);
 *   - the BVH: the bytes Embree reports through rtcSetDeviceMemoryMonitorFunction during
 *     rtcCommitScene (net: allocations minus frees, and the peak), with its own copy of the
 *     vertex and index buffers counted apart; and the growth of this process's resident set
 *     around the commit (/proc/self/statm), which also sees what the monitor does not;
 *   - the gather's per-facet record (sizeof rs_facet_gather) and a K entry (sizeof rs_kentry).
 * bench/mpi_scale.py --memory adds the free-space map and the kernel from the stage's JSON.
 *   rhoscan-facet-bytes MESH.ply */
#include <embree3/rtcore.h>
#include <stdatomic.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>
#include "common/err.h"
#include "common/mesh.h"
#include "light/gather.h"

static _Atomic long long monitor_now, monitor_peak;

/* Embree calls this before every allocation (bytes > 0) and after every free (< 0). */
static bool count_bytes(void *user, ssize_t bytes, bool post)
{
    (void)user;
    (void)post;
    long long now = atomic_fetch_add(&monitor_now, (long long)bytes) + (long long)bytes;
    long long peak = atomic_load(&monitor_peak);
    while (now > peak && !atomic_compare_exchange_weak(&monitor_peak, &peak, now)) {
    }
    return true;
}

static double resident_bytes(void)
{
    long pages = 0, resident = 0;
    FILE *f = fopen("/proc/self/statm", "r");
    if (f) {
        if (fscanf(f, "%ld %ld", &pages, &resident) != 2) resident = 0;
        fclose(f);
    }
    return (double)resident * (double)sysconf(_SC_PAGESIZE);
}

static void print_part(const char *what, double bytes, size_t nfaces)
{
    printf("%-34s %14.0f bytes %9.1f bytes/facet\n", what, bytes, bytes / (double)nfaces);
}

int main(int argc, char **argv)
{
    if (argc != 2 || argv[1][0] == '-') {
        fprintf(stderr, "usage: rhoscan-facet-bytes MESH.ply   (bytes per facet of the mesh and its BVH)\n");
        return 2;
    }
    rs_err err = {0};
    rs_mesh *m = rs_mesh_read(argv[1], NULL, &err);
    if (!m) {
        char msg[2048];
        rs_err_format(&err, msg, sizeof msg);
        fprintf(stderr, "rhoscan-facet-bytes: %s\n", msg);
        return 1;
    }
    RTCDevice dev = rtcNewDevice("threads=1");
    if (!dev) {
        fprintf(stderr, "rhoscan-facet-bytes: Embree device creation failed\n");
        rs_mesh_free(m);
        return 1;
    }
    rtcSetDeviceMemoryMonitorFunction(dev, count_bytes, NULL);
    RTCScene scene = rtcNewScene(dev);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_HIGH);
    RTCGeometry geom = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    float *vb = rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), m->nverts);
    unsigned *ib =
        rtcSetNewGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), m->nfaces);
    if (!vb || !ib) {
        fprintf(stderr, "rhoscan-facet-bytes: out of memory for Embree's buffers\n");
        return 1;
    }
    memcpy(vb, m->verts, m->nverts * 3 * sizeof(float));
    memcpy(ib, m->tris, m->nfaces * 3 * sizeof(unsigned));
    rtcCommitGeometry(geom);
    rtcAttachGeometry(scene, geom);
    rtcReleaseGeometry(geom);
    long long buffers = atomic_load(&monitor_now);
    double rss0 = resident_bytes();
    atomic_store(&monitor_peak, buffers);
    rtcCommitScene(scene);
    double rss1 = resident_bytes();
    long long built = atomic_load(&monitor_now), peak = atomic_load(&monitor_peak);
    if (rtcGetDeviceError(dev) != RTC_ERROR_NONE) {
        fprintf(stderr, "rhoscan-facet-bytes: Embree could not build the BVH\n");
        return 1;
    }
    size_t nf = m->nfaces;
    printf("%s: %zu vertices, %zu facets (%.2f vertices a facet)\n", argv[1], m->nverts, nf,
           (double)m->nverts / (double)nf);
    print_part("mesh (rs_mesh)", (double)m->nverts * 12.0 + (double)nf * 12.0, nf);
    print_part("face normals (rs_scene)", (double)nf * 12.0, nf);
    print_part("Embree's vertex and index copies", (double)buffers, nf);
    print_part("BVH, monitor, kept after commit", (double)(built - buffers), nf);
    print_part("BVH, monitor, peak during commit", (double)(peak - buffers), nf);
    print_part("BVH, resident set growth", rss1 - rss0, nf);
    print_part("gather record (rs_facet_gather)", (double)sizeof(rs_facet_gather) * (double)nf, nf);
    printf("%-34s %14zu bytes\n", "K entry (rs_kentry)", sizeof(rs_kentry));
    rtcReleaseScene(scene);
    rtcReleaseDevice(dev);
    rs_mesh_free(m);
    return 0;
}

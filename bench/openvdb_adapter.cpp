/* openvdb_adapter.cpp: OpenVDB behind bench/freespace_libs.h. */
#include "bench/freespace_libs.h"

#include <cmath>
#include <openvdb/math/DDA.h>
#include <openvdb/math/Ray.h>
#include <openvdb/openvdb.h>

struct rs_vdb {
    double cell, lo[3];
    openvdb::MaskGrid::Ptr free_grid, occ_grid;
    openvdb::MaskGrid::Accessor free_acc, occ_acc;
    rs_vdb(double c, const double l[3])
        : cell(c), lo{l[0], l[1], l[2]}, free_grid(openvdb::MaskGrid::create()), occ_grid(openvdb::MaskGrid::create()),
          free_acc(free_grid->getAccessor()), occ_acc(occ_grid->getAccessor())
    {
    }
    openvdb::Vec3d index(const double p[3]) const
    {
        return {(p[0] - lo[0]) / cell, (p[1] - lo[1]) / cell, (p[2] - lo[2]) / cell};
    }
};

extern "C" rs_vdb *rs_vdb_new(double cell_m, const double lo[3])
{
    try {
        openvdb::initialize();
        return new rs_vdb(cell_m, lo);
    } catch (...) {
        return nullptr;
    }
}

extern "C" void rs_vdb_free(rs_vdb *v)
{
    delete v;
}

extern "C" void rs_vdb_carve(rs_vdb *v, const double a[3], const double b[3], int hit)
{
    typedef openvdb::math::Ray<double> RayT;
    openvdb::Vec3d ia = v->index(a), ib = v->index(b), d = ib - ia;
    double len = d.length();
    if (len <= 0) return;
    /* The segment in index space, stopped half a cell short of a surface it returned from (as
     * rs_freespace_carve does). */
    double t1 = hit ? std::fmax(0.0, len - 0.5) : len;
    RayT ray(ia, d / len, 0, t1);
    openvdb::math::DDA<RayT, 0> dda(ray);
    do v->free_acc.setValueOn(dda.voxel());
    while (dda.step());
    if (hit) v->occ_acc.setValueOn(openvdb::Coord::floor(ib));
}

extern "C" int rs_vdb_state(const rs_vdb *v, const double p[3])
{
    openvdb::Coord c = openvdb::Coord::floor(v->index(p));
    if (v->occ_grid->tree().isValueOn(c)) return 2;
    return v->free_grid->tree().isValueOn(c) ? 1 : 0;
}

extern "C" size_t rs_vdb_bytes(const rs_vdb *v)
{
    return v->free_grid->memUsage() + v->occ_grid->memUsage();
}

extern "C" size_t rs_vdb_voxels(const rs_vdb *v)
{
    return v->free_grid->activeVoxelCount();
}

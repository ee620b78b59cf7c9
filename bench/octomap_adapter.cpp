/* octomap_adapter.cpp: OctoMap behind bench/freespace_libs.h. */
#include "bench/freespace_libs.h"

#include <octomap/OcTree.h>

struct rs_octo {
    octomap::OcTree tree;
    octomap::KeyRay ray;
    explicit rs_octo(double res) : tree(res) {}
};

extern "C" rs_octo *rs_octo_new(double resolution_m)
{
    try {
        return new rs_octo(resolution_m);
    } catch (...) {
        return nullptr;
    }
}

extern "C" void rs_octo_free(rs_octo *t)
{
    delete t;
}

extern "C" void rs_octo_carve(rs_octo *t, const double a[3], const double b[3], int hit)
{
    octomap::point3d o((float)a[0], (float)a[1], (float)a[2]), e((float)b[0], (float)b[1], (float)b[2]);
    if (t->tree.computeRayKeys(o, e, t->ray))
        for (const octomap::OcTreeKey &k : t->ray) t->tree.updateNode(k, false, true);
    if (hit) t->tree.updateNode(e, true, true);
}

extern "C" void rs_octo_finish(rs_octo *t)
{
    t->tree.updateInnerOccupancy();
}

extern "C" int rs_octo_state(const rs_octo *t, const double p[3])
{
    const octomap::OcTreeNode *n = t->tree.search(p[0], p[1], p[2]);
    if (!n) return 0;
    return t->tree.isNodeOccupied(n) ? 2 : 1;
}

extern "C" size_t rs_octo_bytes(const rs_octo *t)
{
    return t->tree.memoryUsage();
}

extern "C" size_t rs_octo_leaves(const rs_octo *t)
{
    return t->tree.getNumLeafNodes();
}

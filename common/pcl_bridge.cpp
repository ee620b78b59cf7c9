// pcl_bridge: the Point Cloud Library behind a C header (pcl_bridge.h). PCL stays in this one
// translation unit (it takes ~10 s and 0.8 GB to compile); every entry catches all exceptions.
#include "common/pcl_bridge.h"
#include "common/pcd_header.h"

#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <limits>
#include <new>
#include <string>
#include <vector>

#include <fcntl.h>
#include <unistd.h>

#include <pcl/PCLPointCloud2.h>
#include <pcl/common/io.h>
#include <pcl/console/print.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_types.h>
#include <pcl/search/kdtree.h>
#include <pcl/surface/gp3.h>
#include <pcl/surface/poisson.h>

namespace {

// PCL prints warnings to the console; library code must not print: silence it once.
void quiet()
{
    pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
}

pcl::PointCloud<pcl::PointXYZ>::Ptr to_pcl(const float *xyz, size_t n)
{
    pcl::PointCloud<pcl::PointXYZ>::Ptr c(new pcl::PointCloud<pcl::PointXYZ>);
    c->resize(n);
    for (size_t i = 0; i < n; i++) (*c)[i] = pcl::PointXYZ(xyz[3 * i], xyz[3 * i + 1], xyz[3 * i + 2]);
    c->width = (uint32_t)n;
    c->height = 1;
    c->is_dense = true;
    return c;
}

pcl::PointCloud<pcl::PointNormal>::Ptr to_pcl_normals(const float *xyz, const float *nrm, size_t n)
{
    pcl::PointCloud<pcl::PointNormal>::Ptr c(new pcl::PointCloud<pcl::PointNormal>);
    c->resize(n);
    for (size_t i = 0; i < n; i++) {
        pcl::PointNormal &p = (*c)[i];
        p.x = xyz[3 * i];
        p.y = xyz[3 * i + 1];
        p.z = xyz[3 * i + 2];
        p.normal_x = nrm[3 * i];
        p.normal_y = nrm[3 * i + 1];
        p.normal_z = nrm[3 * i + 2];
        p.curvature = 0;
    }
    c->width = (uint32_t)n;
    c->height = 1;
    return c;
}

// PCL's Poisson code (3rdparty/poisson4) printf()s diagnostics such as "Vertex pair not in
// list" to stdout, which carries data or nothing in rhoscan's programs, and "[WARNING] Initial
// residual too low" to stderr, which is the log's: both point at /dev/null while it runs
// (restored by the destructor, exceptions included).
class StdoutMuted {
  public:
    StdoutMuted()
    {
        std::fflush(stdout);
        std::fflush(stderr);
        int null = open("/dev/null", O_WRONLY);
        for (int fd = 1; fd <= 2; fd++) {
            saved_[fd - 1] = dup(fd);
            if (saved_[fd - 1] >= 0 && null >= 0) dup2(null, fd);
        }
        if (null >= 0) close(null);
    }
    ~StdoutMuted()
    {
        std::fflush(stdout);
        std::fflush(stderr);
        for (int fd = 1; fd <= 2; fd++)
            if (saved_[fd - 1] >= 0) {
                dup2(saved_[fd - 1], fd);
                close(saved_[fd - 1]);
            }
    }
    StdoutMuted(const StdoutMuted &) = delete;
    StdoutMuted &operator=(const StdoutMuted &) = delete;

  private:
    int saved_[2];
};

// Turns any exception into an rs_err; returns -1.
int fail(rs_err *err, const char *what, const char *where)
{
    return rs_err_set(err, RS_ERR_INTERNAL, NULL, 0, "PCL %s: %s", where, what);
}

double field_value(const uint8_t *p, uint8_t type)
{
    switch (type) {
    case pcl::PCLPointField::INT8: {
        int8_t v;
        std::memcpy(&v, p, 1);
        return v;
    }
    case pcl::PCLPointField::UINT8: return *p;
    case pcl::PCLPointField::INT16: {
        int16_t v;
        std::memcpy(&v, p, 2);
        return v;
    }
    case pcl::PCLPointField::UINT16: {
        uint16_t v;
        std::memcpy(&v, p, 2);
        return v;
    }
    case pcl::PCLPointField::INT32: {
        int32_t v;
        std::memcpy(&v, p, 4);
        return v;
    }
    case pcl::PCLPointField::UINT32: {
        uint32_t v;
        std::memcpy(&v, p, 4);
        return v;
    }
    case pcl::PCLPointField::FLOAT32: {
        float v;
        std::memcpy(&v, p, 4);
        return v;
    }
    case pcl::PCLPointField::FLOAT64: {
        double v;
        std::memcpy(&v, p, 8);
        return v;
    }
    default: return std::nan("");
    }
}

// Bytes of one value of a PCL field type (0 for an unknown type).
size_t field_size(uint8_t type)
{
    switch (type) {
    case pcl::PCLPointField::INT8:
    case pcl::PCLPointField::UINT8: return 1;
    case pcl::PCLPointField::INT16:
    case pcl::PCLPointField::UINT16: return 2;
    case pcl::PCLPointField::INT32:
    case pcl::PCLPointField::UINT32:
    case pcl::PCLPointField::FLOAT32: return 4;
    case pcl::PCLPointField::FLOAT64: return 8;
    default: return 0;
    }
}

const pcl::PCLPointField *find_field(const pcl::PCLPointCloud2 &c, const char *name)
{
    for (const auto &f : c.fields)
        if (f.name == name) return &f;
    return nullptr;
}

rs_cloud *read_pcd(const char *path, rs_err *err)
{
    pcl::PCLPointCloud2 blob;
    pcl::PCDReader reader;
    if (reader.read(path, blob) < 0) {
        rs_err_set(err, RS_ERR_INPUT, path, 0,
                   "PCL's PCD reader refused the file; expected a PCD point cloud "
                   "(header VERSION, FIELDS x y z ..., DATA ascii|binary|binary_compressed)");
        return nullptr;
    }
    const pcl::PCLPointField *fx = find_field(blob, "x"), *fy = find_field(blob, "y"), *fz = find_field(blob, "z");
    if (!fx || !fy || !fz) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "no x, y and z fields; expected a point cloud");
        return nullptr;
    }
    const pcl::PCLPointField *fi = find_field(blob, "intensity");
    const pcl::PCLPointField *frgb = find_field(blob, "rgb");
    if (!frgb) frgb = find_field(blob, "rgba");
    // Every field read must lie inside a point's record: PCL does not check the offsets.
    for (const pcl::PCLPointField *f : {fx, fy, fz, fi, frgb}) {
        size_t bytes = !f ? 0 : f == frgb ? 4 : field_size(f->datatype);
        if (f && (bytes == 0 || (size_t)f->offset + bytes > blob.point_step)) {
            rs_err_set(err, RS_ERR_INPUT, path, 0,
                       "field %s (offset %u, %zu bytes) does not fit in a point of %u bytes; expected FIELDS, SIZE, "
                       "TYPE and COUNT that agree",
                       f->name.c_str(), f->offset, bytes, blob.point_step);
            return nullptr;
        }
    }
    size_t n = (size_t)blob.width * blob.height;
    if (blob.point_step && n > SIZE_MAX / blob.point_step) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "WIDTH x HEIGHT = %u x %u points of %u bytes overflow", blob.width,
                   blob.height, blob.point_step);
        return nullptr;
    }
    if (blob.data.size() < n * blob.point_step) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "%zu points of %u bytes but only %zu bytes of data", n, blob.point_step,
                   blob.data.size());
        return nullptr;
    }
    rs_cloud *c = (rs_cloud *)std::calloc(1, sizeof *c);
    if (!c) throw std::bad_alloc();
    c->xyz = (double *)std::malloc((n ? n : 1) * 3 * sizeof(double));
    c->valid = (uint8_t *)std::malloc(n ? n : 1);
    if (fi) c->intensity = (float *)std::malloc((n ? n : 1) * sizeof(float));
    if (frgb) c->rgb = (uint8_t *)std::malloc((n ? n : 1) * 3);
    if (!c->xyz || !c->valid || (fi && !c->intensity) || (frgb && !c->rgb)) {
        rs_cloud_free(c);
        throw std::bad_alloc();
    }
    size_t k = 0;
    for (size_t i = 0; i < n; i++) {
        const uint8_t *p = blob.data.data() + i * blob.point_step;
        double x = field_value(p + fx->offset, fx->datatype), y = field_value(p + fy->offset, fy->datatype),
               z = field_value(p + fz->offset, fz->datatype);
        if (std::isnan(x) || std::isnan(y) || std::isnan(z)) continue;   // PCL's "no return"
        if (!(std::fabs(x) <= RS_CLOUD_MAX_M && std::fabs(y) <= RS_CLOUD_MAX_M && std::fabs(z) <= RS_CLOUD_MAX_M)) {
            rs_cloud_free(c);
            rs_err_set(err, RS_ERR_INPUT, path, 0, "point %zu: coordinates (%g, %g, %g); expected -%g to %g (m)", i, x,
                       y, z, RS_CLOUD_MAX_M, RS_CLOUD_MAX_M);
            return nullptr;
        }
        c->xyz[3 * k] = x;
        c->xyz[3 * k + 1] = y;
        c->xyz[3 * k + 2] = z;
        c->valid[k] = 1;
        if (fi) {
            double v = field_value(p + fi->offset, fi->datatype);
            if (!(std::fabs(v) <= FLT_MAX)) {   // stored as float
                rs_cloud_free(c);
                rs_err_set(err, RS_ERR_INPUT, path, 0,
                           "point %zu: intensity %g; expected a finite number within the float range", i, v);
                return nullptr;
            }
            c->intensity[k] = (float)v;
        }
        if (frgb) {
            // PCL packs colour as 0x00RRGGBB in the bits of a float (rgb) or a uint32 (rgba).
            uint32_t v;
            std::memcpy(&v, p + frgb->offset, 4);
            c->rgb[3 * k] = (uint8_t)(v >> 16);
            c->rgb[3 * k + 1] = (uint8_t)(v >> 8);
            c->rgb[3 * k + 2] = (uint8_t)v;
        }
        k++;
    }
    c->npoints = k;
    if (k == 0) {
        rs_cloud_free(c);
        rs_err_set(err, RS_ERR_INPUT, path, 0, "no point with finite coordinates among %zu", n);
        return nullptr;
    }
    return c;
}

}   // namespace

extern "C" rs_cloud *rs_pcl_read_pcd(const char *path, rs_err *err)
{
    if (rs_pcd_check_file(path, err) != 0) return nullptr;   // PCL trusts the header
    try {
        quiet();
        return read_pcd(path, err);
    } catch (const std::bad_alloc &) {
        rs_err_set(err, RS_ERR_SYSTEM, path, 0, "out of memory reading the PCD file");
    } catch (const std::exception &e) {
        rs_err_set(err, RS_ERR_INPUT, path, 0, "PCL's PCD reader: %s", e.what());
    } catch (...) {
        rs_err_set(err, RS_ERR_INTERNAL, path, 0, "PCL's PCD reader: unknown exception");
    }
    return nullptr;
}

extern "C" int rs_pcl_outliers(const float *xyz, size_t n, int k, double std_mul, uint8_t *keep, rs_err *err)
{
    try {
        quiet();
        std::memset(keep, 0, n);
        auto c = to_pcl(xyz, n);
        pcl::StatisticalOutlierRemoval<pcl::PointXYZ> sor;
        sor.setInputCloud(c);
        sor.setMeanK(k);
        sor.setStddevMulThresh(std_mul);
        pcl::Indices kept;
        sor.filter(kept);
        for (auto i : kept) keep[i] = 1;
        return 0;
    } catch (const std::bad_alloc &) {
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory in outlier removal of %zu points", n);
    } catch (const std::exception &e) {
        return fail(err, e.what(), "outlier removal");
    } catch (...) {
        return fail(err, "unknown exception", "outlier removal");
    }
}

extern "C" int rs_pcl_knn_mean(const float *xyz, size_t n, const float *query, size_t m, int k, float *mean, float *kth,
                               rs_err *err)
{
    try {
        quiet();
        auto c = to_pcl(xyz, n);
        // The search and the arithmetic of StatisticalOutlierRemoval::applyFilterIndices (PCL 1.13):
        // k + 1 neighbours (the first is the point itself), the mean of sqrt of their squared
        // distances in double, stored as float. FLANN returns them sorted for k + 1 <= 250, so the
        // sum's order is the distances' whatever the tree.
        pcl::search::KdTree<pcl::PointXYZ> tree(false);
        tree.setInputCloud(c);
        pcl::Indices nn(k + 1);
        std::vector<float> d2(k + 1);
        for (size_t i = 0; i < m; i++) {
            pcl::PointXYZ q(query[3 * i], query[3 * i + 1], query[3 * i + 2]);
            if (tree.nearestKSearch(q, k + 1, nn, d2) < k + 1) {
                mean[i] = 0, kth[i] = INFINITY;
                continue;
            }
            double sum = 0.0;
            for (int j = 1; j < k + 1; ++j) sum += std::sqrt((double)d2[j]);
            mean[i] = static_cast<float>(sum / k);
            kth[i] = std::sqrt(d2[k]);
        }
        return 0;
    } catch (const std::bad_alloc &) {
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory in the neighbour search of %zu points", n);
    } catch (const std::exception &e) {
        return fail(err, e.what(), "neighbour search");
    } catch (...) {
        return fail(err, "unknown exception", "neighbour search");
    }
}

extern "C" int rs_pcl_voxel(const float *xyz, const float *intensity, const uint8_t *rgb, size_t n, double leaf_m,
                            size_t *nout, float **xyz_out, float **intensity_out, uint8_t **rgb_out, rs_err *err)
{
    *xyz_out = nullptr;
    *intensity_out = nullptr;
    *rgb_out = nullptr;
    *nout = 0;
    try {
        quiet();
        // Intensity rides in the curvature field and colour in rgb: VoxelGrid averages every
        // field of the point type (colour per channel), so attributes stay with their points.
        pcl::PointCloud<pcl::PointXYZRGBNormal>::Ptr c(new pcl::PointCloud<pcl::PointXYZRGBNormal>);
        c->resize(n);
        float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t i = 0; i < n; i++) {
            pcl::PointXYZRGBNormal &p = (*c)[i];
            p.x = xyz[3 * i];
            p.y = xyz[3 * i + 1];
            p.z = xyz[3 * i + 2];
            for (int j = 0; j < 3; j++) {
                lo[j] = std::fmin(lo[j], xyz[3 * i + j]);
                hi[j] = std::fmax(hi[j], xyz[3 * i + j]);
            }
            p.normal_x = p.normal_y = p.normal_z = 0;
            p.curvature = intensity ? intensity[i] : 0.0f;
            p.r = rgb ? rgb[3 * i] : 0;
            p.g = rgb ? rgb[3 * i + 1] : 0;
            p.b = rgb ? rgb[3 * i + 2] : 0;
            p.a = 255;
        }
        double cells = 1;
        for (int j = 0; j < 3; j++) cells *= std::floor((hi[j] - lo[j]) / leaf_m) + 1;
        if (n && cells > (double)std::numeric_limits<int32_t>::max())
            return rs_err_set(err, RS_ERR_INPUT, NULL, 0,
                              "voxel size %g m over a %.4g x %.4g x %.4g m cloud makes %.3g "
                              "cells; PCL's VoxelGrid indexes at most 2^31: expected a larger voxel size",
                              leaf_m, hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], cells);
        pcl::VoxelGrid<pcl::PointXYZRGBNormal> vg;
        vg.setInputCloud(c);
        vg.setLeafSize((float)leaf_m, (float)leaf_m, (float)leaf_m);
        vg.setDownsampleAllData(true);
        pcl::PointCloud<pcl::PointXYZRGBNormal> out;
        vg.filter(out);
        size_t m = out.size();
        *xyz_out = (float *)std::malloc((m ? m : 1) * 3 * sizeof(float));
        if (intensity) *intensity_out = (float *)std::malloc((m ? m : 1) * sizeof(float));
        if (rgb) *rgb_out = (uint8_t *)std::malloc((m ? m : 1) * 3);
        if (!*xyz_out || (intensity && !*intensity_out) || (rgb && !*rgb_out)) throw std::bad_alloc();
        for (size_t i = 0; i < m; i++) {
            const pcl::PointXYZRGBNormal &p = out[i];
            (*xyz_out)[3 * i] = p.x;
            (*xyz_out)[3 * i + 1] = p.y;
            (*xyz_out)[3 * i + 2] = p.z;
            if (intensity) (*intensity_out)[i] = p.curvature;
            if (rgb) {
                (*rgb_out)[3 * i] = p.r;
                (*rgb_out)[3 * i + 1] = p.g;
                (*rgb_out)[3 * i + 2] = p.b;
            }
        }
        *nout = m;
        return 0;
    } catch (const std::bad_alloc &) {
        rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory in voxel downsampling of %zu points", n);
    } catch (const std::exception &e) {
        fail(err, e.what(), "voxel downsampling");
    } catch (...) {
        fail(err, "unknown exception", "voxel downsampling");
    }
    std::free(*xyz_out);
    std::free(*intensity_out);
    std::free(*rgb_out);
    *xyz_out = nullptr;
    *intensity_out = nullptr;
    *rgb_out = nullptr;
    return -1;
}

extern "C" int rs_pcl_normals(const float *xyz, size_t n, int k, const float *viewpoints, int threads, float *normals,
                              rs_err *err)
{
    try {
        quiet();
        auto c = to_pcl(xyz, n);
        pcl::NormalEstimationOMP<pcl::PointXYZ, pcl::Normal> ne(threads > 0 ? (unsigned)threads : 0u);
        pcl::search::KdTree<pcl::PointXYZ>::Ptr tree(new pcl::search::KdTree<pcl::PointXYZ>);
        ne.setInputCloud(c);
        ne.setSearchMethod(tree);
        ne.setKSearch(k);
        pcl::PointCloud<pcl::Normal> nn;
        ne.compute(nn);
        for (size_t i = 0; i < n; i++) {
            float v[3] = {nn[i].normal_x, nn[i].normal_y, nn[i].normal_z};
            if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2])) v[0] = v[1] = v[2] = 0;
            // Toward the scanner that saw the point: the side of the surface that was observed.
            double d = 0;
            for (int j = 0; j < 3; j++) d += v[j] * (viewpoints[3 * i + j] - xyz[3 * i + j]);
            float s = d < 0 ? -1.0f : 1.0f;
            for (int j = 0; j < 3; j++) normals[3 * i + j] = s * v[j];
        }
        return 0;
    } catch (const std::bad_alloc &) {
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory estimating normals of %zu points", n);
    } catch (const std::exception &e) {
        return fail(err, e.what(), "normal estimation");
    } catch (...) {
        return fail(err, "unknown exception", "normal estimation");
    }
}

extern "C" int rs_pcl_greedy(const float *xyz, const float *normals, size_t n, double radius_m, double mu, int max_nn,
                             uint32_t **tris, size_t *ntris, rs_err *err)
{
    *tris = nullptr;
    *ntris = 0;
    try {
        quiet();
        auto c = to_pcl_normals(xyz, normals, n);
        pcl::search::KdTree<pcl::PointNormal>::Ptr tree(new pcl::search::KdTree<pcl::PointNormal>);
        tree->setInputCloud(c);
        pcl::GreedyProjectionTriangulation<pcl::PointNormal> gp3;
        gp3.setSearchRadius(radius_m);
        gp3.setMu(mu);
        gp3.setMaximumNearestNeighbors(max_nn);
        gp3.setMaximumSurfaceAngle(M_PI / 4);   // 45 degrees between neighbouring normals
        gp3.setMinimumAngle(M_PI / 18);         // 10 degrees
        gp3.setMaximumAngle(2 * M_PI / 3);      // 120 degrees
        gp3.setNormalConsistency(true);         // the normals are oriented already
        gp3.setInputCloud(c);
        gp3.setSearchMethod(tree);
        std::vector<pcl::Vertices> polys;
        gp3.reconstruct(polys);
        uint32_t *t = (uint32_t *)std::malloc((polys.size() ? polys.size() : 1) * 3 * sizeof(uint32_t));
        if (!t) throw std::bad_alloc();
        size_t m = 0;
        for (const auto &p : polys) {
            if (p.vertices.size() != 3) continue;
            uint32_t a = (uint32_t)p.vertices[0], b = (uint32_t)p.vertices[1], d = (uint32_t)p.vertices[2];
            // Wind counter-clockwise seen from the side the vertex normals point to.
            float e1[3], e2[3], cr[3], ns[3];
            for (int j = 0; j < 3; j++) {
                e1[j] = xyz[3 * b + j] - xyz[3 * a + j];
                e2[j] = xyz[3 * d + j] - xyz[3 * a + j];
                ns[j] = normals[3 * a + j] + normals[3 * b + j] + normals[3 * d + j];
            }
            cr[0] = e1[1] * e2[2] - e1[2] * e2[1];
            cr[1] = e1[2] * e2[0] - e1[0] * e2[2];
            cr[2] = e1[0] * e2[1] - e1[1] * e2[0];
            int flip = cr[0] * ns[0] + cr[1] * ns[1] + cr[2] * ns[2] < 0;
            t[3 * m] = a;
            t[3 * m + 1] = flip ? d : b;
            t[3 * m + 2] = flip ? b : d;
            m++;
        }
        *tris = t;
        *ntris = m;
        return 0;
    } catch (const std::bad_alloc &) {
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory triangulating %zu points", n);
    } catch (const std::exception &e) {
        return fail(err, e.what(), "greedy projection triangulation");
    } catch (...) {
        return fail(err, "unknown exception", "greedy projection triangulation");
    }
}

extern "C" int rs_pcl_poisson(const float *xyz, const float *normals, size_t n, int depth, float **verts,
                              size_t *nverts, uint32_t **tris, size_t *ntris, rs_err *err)
{
    *verts = nullptr;
    *tris = nullptr;
    *nverts = *ntris = 0;
    try {
        quiet();
        auto c = to_pcl_normals(xyz, normals, n);
        pcl::Poisson<pcl::PointNormal> poisson;
        poisson.setDepth(depth);
        poisson.setInputCloud(c);
        pcl::PointCloud<pcl::PointNormal> pts;
        std::vector<pcl::Vertices> polys;
        {
            StdoutMuted mute;
            poisson.reconstruct(pts, polys);
        }
        float *v = (float *)std::malloc((pts.size() ? pts.size() : 1) * 3 * sizeof(float));
        uint32_t *t = (uint32_t *)std::malloc((polys.size() ? polys.size() : 1) * 3 * sizeof(uint32_t));
        if (!v || !t) {
            std::free(v);
            std::free(t);
            throw std::bad_alloc();
        }
        for (size_t i = 0; i < pts.size(); i++) {
            v[3 * i] = pts[i].x;
            v[3 * i + 1] = pts[i].y;
            v[3 * i + 2] = pts[i].z;
        }
        size_t m = 0;
        for (const auto &p : polys) {
            if (p.vertices.size() != 3) continue;
            for (int j = 0; j < 3; j++) t[3 * m + j] = (uint32_t)p.vertices[j];
            m++;
        }
        *verts = v;
        *nverts = pts.size();
        *tris = t;
        *ntris = m;
        return 0;
    } catch (const std::bad_alloc &) {
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory in Poisson reconstruction of %zu points", n);
    } catch (const std::exception &e) {
        return fail(err, e.what(), "Poisson reconstruction");
    } catch (...) {
        return fail(err, "unknown exception", "Poisson reconstruction");
    }
}

extern "C" int rs_pcl_nearest(const float *xyz, size_t n, const float *query, size_t m, int skip_self, float *dist,
                              uint32_t *index, rs_err *err)
{
    try {
        quiet();
        auto c = to_pcl(xyz, n);
        pcl::KdTreeFLANN<pcl::PointXYZ> tree;
        tree.setInputCloud(c);
        int k = skip_self ? 2 : 1;
        pcl::Indices idx(k);
        std::vector<float> d2(k);
        for (size_t i = 0; i < m; i++) {
            pcl::PointXYZ q(query[3 * i], query[3 * i + 1], query[3 * i + 2]);
            bool found = tree.nearestKSearch(q, k, idx, d2) == k;
            dist[i] = found ? std::sqrt(d2[k - 1]) : INFINITY;
            if (index) index[i] = found ? (uint32_t)idx[k - 1] : UINT32_MAX;
        }
        return 0;
    } catch (const std::bad_alloc &) {
        return rs_err_set(err, RS_ERR_SYSTEM, NULL, 0, "out of memory in a nearest-point search of %zu points", n);
    } catch (const std::exception &e) {
        return fail(err, e.what(), "nearest-point search");
    } catch (...) {
        return fail(err, "unknown exception", "nearest-point search");
    }
}

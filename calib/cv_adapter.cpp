// cv_adapter: OpenCV behind the C header cv_adapter.h. Each extern "C" entry wraps its body in
// try/catch: an exception crossing into C code would be undefined behaviour.
#include "calib/cv_adapter.h"

#include <cerrno>
#include <climits>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>
#include <vector>

#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/photo.hpp>

namespace {

struct field_error {
    std::string what;
};

void set_msg(char *msg, size_t n, const std::string &s)
{
    if (!msg || !n) return;
    std::snprintf(msg, n, "%s", s.c_str());
    // OpenCV's messages end in a newline: the caller adds its own context around them.
    for (size_t k = std::strlen(msg); k > 0 && (msg[k - 1] == '\n' || msg[k - 1] == ' '); k--) msg[k - 1] = 0;
}

// The one place that turns the exception in flight into a message: the extern "C" entries end
// in catch (...) { return fail_with_current_exception(msg, msg_size); }.
int fail_with_current_exception(char *msg, size_t msg_size)
{
    try {
        throw;
    } catch (const cv::Exception &e) {
        set_msg(msg, msg_size, std::string("OpenCV: ") + e.what());
    } catch (const std::exception &e) {
        set_msg(msg, msg_size, e.what());
    } catch (...) {
        set_msg(msg, msg_size, "unknown exception");
    }
    return -1;
}

// A matrix field read into doubles: returns the number of entries (0 when the field is absent).
int read_matrix(const cv::FileNode &cam, const char *key, int index, double *out, int max_entries)
{
    cv::FileNode node = cam[key];
    if (node.empty()) return 0;
    cv::Mat m;
    try {
        node >> m;
    } catch (const cv::Exception &) {
        throw field_error{"camera " + std::to_string(index) + ": " + key +
                          " is not an !!opencv-matrix (expected rows, cols, dt and data)"};
    }
    if (m.empty())
        throw field_error{"camera " + std::to_string(index) + ": " + key + " is empty or not an !!opencv-matrix"};
    if (static_cast<int>(m.total()) * m.channels() > max_entries)
        throw field_error{"camera " + std::to_string(index) + ": " + key + " has " +
                          std::to_string(m.total() * m.channels()) + " entries, expected at most " +
                          std::to_string(max_entries)};
    cv::Mat d;
    m.reshape(1, 1).convertTo(d, CV_64F);
    for (int i = 0; i < d.cols; i++) out[i] = d.at<double>(0, i);
    return d.cols;
}

// Up to max_entries reals from an !!opencv-matrix or a plain YAML sequence ([a, b, c]).
int read_reals(const cv::FileNode &cam, const char *key, int index, double *out, int max_entries)
{
    cv::FileNode node = cam[key];
    if (node.empty() || !node.isSeq()) return read_matrix(cam, key, index, out, max_entries);
    int n = static_cast<int>(node.size());
    if (n > max_entries)
        throw field_error{"camera " + std::to_string(index) + ": " + key + " has " + std::to_string(n) +
                          " entries, expected at most " + std::to_string(max_entries)};
    for (int i = 0; i < n; i++) {
        if (!node[i].isReal() && !node[i].isInt())
            throw field_error{"camera " + std::to_string(index) + ": " + key + " entry " + std::to_string(i) +
                              " is not a number"};
        out[i] = static_cast<double>(node[i]);
    }
    return n;
}

// A scalar as the file wrote it, for messages.
std::string as_written(const cv::FileNode &node)
{
    char buf[64];
    if (node.isInt()) return std::to_string(static_cast<int>(node));
    if (node.isReal()) {
        std::snprintf(buf, sizeof buf, "%.17g", static_cast<double>(node));
        return buf;
    }
    if (node.isString()) return "\"" + std::string(node).substr(0, 40) + "\"";
    return "(not a scalar)";
}

// A scalar size field as written: *has 0 when absent, 1 for a number, 2 for anything else.
double read_size(const cv::FileNode &cam, const char *key, int *has)
{
    cv::FileNode node = cam[key];
    *has = node.empty() ? 0 : node.isInt() || node.isReal() ? 1 : 2;
    if (node.isInt()) return static_cast<double>(static_cast<int>(node));
    if (node.isReal()) return static_cast<double>(node);
    return std::nan("");
}

// OpenCV's YAML parser reads an integer with strtol and keeps it in an int, so 4294967297 becomes
// 1 without a word. The text is scanned first: an integer token that does not fit 32 bits is
// returned with its line and the key it belongs to (the line's, or the last one above it).
bool find_wide_integer(const char *path, long *line, std::string *key, std::string *token)
{
    FILE *f = std::fopen(path, "rb");
    if (!f) return false;
    std::string text;
    char buf[65536];
    for (size_t n; (n = std::fread(buf, 1, sizeof buf, f)) > 0;) text.append(buf, n);
    std::fclose(f);
    std::string last_key;
    long lineno = 0;
    for (size_t at = 0; at <= text.size();) {
        size_t nl = text.find('\n', at);
        if (nl == std::string::npos) nl = text.size();
        std::string l = text.substr(at, nl - at);
        at = nl + 1;
        lineno++;
        if (!l.empty() && l[0] == '%') continue;   // the %YAML directive
        bool quoted = false;
        size_t colon = std::string::npos;
        for (size_t k = 0; k < l.size(); k++) {
            if (l[k] == '"') quoted = !quoted;
            if (!quoted && l[k] == '#' && (k == 0 || l[k - 1] == ' ' || l[k - 1] == '\t')) {
                l.resize(k);
                break;
            }
            if (!quoted && l[k] == ':' && colon == std::string::npos) colon = k;
        }
        if (colon != std::string::npos) {
            size_t b = l.find_first_not_of(" \t-");
            last_key = b < colon ? l.substr(b, colon - b) : "";
            while (!last_key.empty() && (last_key.back() == ' ' || last_key.back() == '\t')) last_key.pop_back();
        }
        quoted = false;
        for (size_t k = colon == std::string::npos ? 0 : colon + 1; k < l.size();) {
            if (l[k] == '"') quoted = !quoted;
            if (quoted || std::strchr(" \t,[]{}:", l[k])) {
                k++;
                continue;
            }
            size_t e = l.find_first_of(" \t,[]{}:\"", k);
            if (e == std::string::npos) e = l.size();
            std::string tok = l.substr(k, e - k);
            k = e;
            size_t d = tok[0] == '-' || tok[0] == '+' ? 1 : 0;
            bool hex = tok.size() > d + 2 && tok[d] == '0' && (tok[d + 1] == 'x' || tok[d + 1] == 'X');
            if (d >= tok.size() ||
                tok.find_first_not_of(hex ? "0123456789abcdefABCDEF" : "0123456789", hex ? d + 2 : d) !=
                    std::string::npos)
                continue;   // not an integer: a real, a word, a tag
            errno = 0;
            long long v = std::strtoll(tok.c_str(), nullptr, 0);
            if (errno == ERANGE || v < INT_MIN || v > INT_MAX) {
                *line = lineno;
                *key = last_key;
                *token = tok.substr(0, 40);
                return true;
            }
        }
    }
    return false;
}

}   // namespace

extern "C" int rs_cv_rig_read(const char *path, rs_cv_camera **cams, int *count, int *declared_count, long *line,
                              char *msg, size_t msg_size)
{
    *cams = nullptr;
    *count = 0;
    *declared_count = -1;
    *line = 0;
    rs_cv_camera *out = nullptr;
    try {
        std::string key, token;
        if (find_wide_integer(path, line, &key, &token)) {
            set_msg(msg, msg_size,
                    key + " = " + token +
                        ": the integer does not fit in 32 bits (OpenCV would read it wrapped); expected " +
                        (key == "image_width" || key == "image_height" ? "an integer from 1 to 65536 (px)"
                                                                       : "an integer from -2147483648 to 2147483647"));
            return -1;
        }
        cv::FileStorage fs(path, cv::FileStorage::READ);
        if (!fs.isOpened()) {
            set_msg(msg, msg_size,
                    "cannot open as an OpenCV FileStorage file (expected %YAML:1.0 with "
                    "camera_count and cameras)");
            return -1;
        }
        cv::FileNode cc = fs["camera_count"];
        if (!cc.empty()) {
            // A count too large for an int is read by OpenCV as a real; a negative one is no count.
            if (!cc.isInt() || static_cast<int>(cc) < 0)
                throw field_error{"camera_count = " + as_written(cc) +
                                  ": expected an integer from 0 to 2147483647, the number of cameras listed"};
            *declared_count = static_cast<int>(cc);
        }
        cv::FileNode seq = fs["cameras"];
        if (seq.empty() || !seq.isSeq())
            throw field_error{"no `cameras` sequence (expected `cameras:` followed by one `- name: ...` map per "
                              "camera)"};
        int n = static_cast<int>(seq.size());
        out = static_cast<rs_cv_camera *>(std::calloc(n > 0 ? n : 1, sizeof *out));
        if (!out) throw std::bad_alloc();
        for (int i = 0; i < n; i++) {
            cv::FileNode cam = seq[i];
            rs_cv_camera *c = &out[i];
            if (!cam.isMap()) throw field_error{"camera " + std::to_string(i) + " is not a map of fields"};
            std::string name = cam["name"].empty() ? "cam" + std::to_string(i) : std::string(cam["name"]);
            std::snprintf(c->name, sizeof c->name, "%s", name.c_str());
            std::string model = cam["model"].empty() ? "pinhole" : std::string(cam["model"]);
            std::snprintf(c->model, sizeof c->model, "%s", model.c_str());
            c->width = read_size(cam, "image_width", &c->has_width);
            c->height = read_size(cam, "image_height", &c->has_height);
            c->has_matrix = read_matrix(cam, "camera_matrix", i, c->camera_matrix, 9) == 9;
            if (!cam["camera_matrix"].empty() && !c->has_matrix)
                throw field_error{"camera " + std::to_string(i) + ": camera_matrix must be 3 x 3"};
            c->distortion_count = read_matrix(cam, "distortion_coefficients", i, c->distortion, 8);
            c->has_rotation = read_matrix(cam, "R_rig_cam", i, c->r_rig_cam, 9) == 9;
            if (!cam["R_rig_cam"].empty() && !c->has_rotation)
                throw field_error{"camera " + std::to_string(i) + ": R_rig_cam must be 3 x 3"};
            c->has_translation = read_matrix(cam, "t_rig_cam", i, c->t_rig_cam, 3) == 3;
            if (!cam["t_rig_cam"].empty() && !c->has_translation)
                throw field_error{"camera " + std::to_string(i) + ": t_rig_cam must have 3 entries"};
            cv::FileNode gain = cam["gain"];
            c->has_gain = gain.empty() ? 0 : gain.isReal() || gain.isInt() ? 1 : 2;
            if (c->has_gain == 1) c->gain = static_cast<double>(gain);
            c->vignetting_count = read_reals(cam, "vignetting", i, c->vignetting, 4);
            cv::FileNode mask = cam["valid_mask"];
            if (!mask.empty()) {
                if (!mask.isString())
                    throw field_error{"camera " + std::to_string(i) + ": valid_mask must be an image file's path"};
                std::snprintf(c->valid_mask, sizeof c->valid_mask, "%s", std::string(mask).c_str());
            }
        }
        *cams = out;
        *count = n;
        return 0;
    } catch (const field_error &e) {
        set_msg(msg, msg_size, e.what);
    } catch (const cv::Exception &e) {
        set_msg(msg, msg_size, std::string("not a valid FileStorage YAML file: ") + e.what());
    } catch (const std::exception &e) {
        set_msg(msg, msg_size, std::string("reading the rig file failed: ") + e.what());
    } catch (...) {
        set_msg(msg, msg_size, "reading the rig file failed: unknown exception");
    }
    std::free(out);
    return -1;
}

extern "C" int rs_cv_image_read(const char *path, float **data, int *width, int *height, int *channels,
                                int *integer_bits, char *msg, size_t msg_size)
{
    *data = nullptr;
    try {
        cv::Mat m = cv::imread(path, cv::IMREAD_ANYDEPTH | cv::IMREAD_ANYCOLOR);
        if (m.empty()) {
            set_msg(msg, msg_size, "OpenCV cannot decode this image file");
            return -1;
        }
        int depth = m.depth();
        *integer_bits = depth == CV_8U ? 8 : depth == CV_16U ? 16 : 0;
        double scale = depth == CV_8U ? 1.0 / 255 : depth == CV_16U ? 1.0 / 65535 : 1.0;
        cv::Mat f;
        m.convertTo(f, CV_32F, scale);
        if (f.channels() == 4)
            cv::cvtColor(f, f, cv::COLOR_BGRA2RGB);
        else if (f.channels() == 3)
            cv::cvtColor(f, f, cv::COLOR_BGR2RGB);
        else if (f.channels() != 1) {
            set_msg(msg, msg_size, "image has " + std::to_string(f.channels()) + " channels: expected 1, 3 or 4");
            return -1;
        }
        f = f.clone();   // continuous
        size_t n = f.total() * f.channels();
        float *p = static_cast<float *>(std::malloc(n * sizeof *p));
        if (!p) throw std::bad_alloc();
        std::memcpy(p, f.ptr<float>(), n * sizeof *p);
        *data = p;
        *width = f.cols;
        *height = f.rows;
        *channels = f.channels();
        return 0;
    } catch (...) {
        return fail_with_current_exception(msg, msg_size);
    }
}

extern "C" int rs_cv_merge_debevec(const unsigned char *const *images, const float *times_s, int count, int width,
                                   int height, const float *response, float *out, float *response_out, char *msg,
                                   size_t msg_size)
{
    try {
        std::vector<cv::Mat> imgs;
        std::vector<float> times(times_s, times_s + count);
        for (int i = 0; i < count; i++) {
            // OpenCV's photo module expects BGR; the merge is per channel, so RGB order is kept
            // as long as the response is read back in the same order.
            imgs.emplace_back(height, width, CV_8UC3, const_cast<unsigned char *>(images[i]));
        }
        cv::Mat resp;
        if (response) {
            resp = cv::Mat(256, 1, CV_32FC3, const_cast<float *>(response)).clone();
        } else {
            cv::Ptr<cv::CalibrateDebevec> cal = cv::createCalibrateDebevec();
            cal->process(imgs, resp, times);
        }
        if (response_out) {
            cv::Mat r32;
            resp.convertTo(r32, CV_32FC3);
            std::memcpy(response_out, r32.ptr<float>(), 256 * 3 * sizeof(float));
        }
        cv::Mat hdr;
        cv::createMergeDebevec()->process(imgs, hdr, times, resp);
        cv::Mat outm(height, width, CV_32FC3, out);
        hdr.convertTo(outm, CV_32FC3);
        return 0;
    } catch (...) {
        return fail_with_current_exception(msg, msg_size);
    }
}

extern "C" int rs_cv_project(int fisheye, const double *camera_matrix, const double *dist, int n, const double *points,
                             double *pixels, char *msg, size_t msg_size)
{
    try {
        cv::Mat k(3, 3, CV_64F, const_cast<double *>(camera_matrix));
        cv::Mat d(1, fisheye ? 4 : 5, CV_64F, const_cast<double *>(dist));
        cv::Mat pts(n, 1, CV_64FC3, const_cast<double *>(points));
        cv::Mat zero = cv::Mat::zeros(3, 1, CV_64F);
        cv::Mat out;
        if (fisheye)
            cv::fisheye::projectPoints(pts, out, zero, zero, k, d);
        else
            cv::projectPoints(pts, zero, zero, k, d, out);
        cv::Mat o64;
        out.convertTo(o64, CV_64FC2);
        std::memcpy(pixels, o64.ptr<double>(), static_cast<size_t>(n) * 2 * sizeof(double));
        return 0;
    } catch (...) {
        return fail_with_current_exception(msg, msg_size);
    }
}

extern "C" int rs_cv_edge_distance(const float *image, int width, int height, double sigma_px, double lo, double hi,
                                   unsigned char *edges, float *dist, long *edge_count, char *msg, size_t msg_size)
{
    try {
        cv::Mat img(height, width, CV_32F, const_cast<float *>(image)), smooth;
        if (sigma_px > 0)
            cv::GaussianBlur(img, smooth, cv::Size(0, 0), sigma_px, sigma_px, cv::BORDER_REFLECT);
        else
            smooth = img;
        // Sobel's 3 x 3 kernel weighs the difference over 2 px by 1 + 2 + 1: scale 1/8 gives the
        // derivative per pixel. Canny takes 16-bit derivatives: a fixed gain keeps the thresholds
        // in the image's own units (saturation at 32767 / gain is far above any real edge).
        const double gain = 1000.0;
        cv::Mat dx, dy, dx16, dy16;
        cv::Sobel(smooth, dx, CV_32F, 1, 0, 3, 1.0 / 8.0, 0, cv::BORDER_REFLECT);
        cv::Sobel(smooth, dy, CV_32F, 0, 1, 3, 1.0 / 8.0, 0, cv::BORDER_REFLECT);
        dx.convertTo(dx16, CV_16S, gain);
        dy.convertTo(dy16, CV_16S, gain);
        cv::Mat e(height, width, CV_8U, edges);
        cv::Mat canny;
        cv::Canny(dx16, dy16, canny, lo * gain, hi * gain, true);
        canny.copyTo(e);
        *edge_count = cv::countNonZero(e);
        if (*edge_count == 0) return 0;
        // distanceTransform measures the distance to the nearest zero pixel: edges must be zero.
        cv::Mat inv, d(height, width, CV_32F, dist);
        cv::bitwise_not(e, inv);
        cv::Mat dt;
        cv::distanceTransform(inv, dt, cv::DIST_L2, cv::DIST_MASK_PRECISE, CV_32F);
        dt.copyTo(d);
        return 0;
    } catch (...) {
        return fail_with_current_exception(msg, msg_size);
    }
}

extern "C" void rs_cv_free(void *p)
{
    std::free(p);
}

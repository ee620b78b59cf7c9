// exr_dwa: the C++ fallback for EXR compressions the C library lacks (see exr_dwa.h).
#include "common/exr_dwa.h"

#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfIO.h>
#include <ImfInputFile.h>
#include <algorithm>
#include <cstdio>
#include <cstdint>
#include <cstring>
#include <exception>
#include <vector>

namespace {

// An Imf::IStream over a memory buffer, so that the fuzzer and the file path share one reader.
class MemoryStream : public Imf::IStream {
  public:
    MemoryStream(const char *data, size_t size) : Imf::IStream("memory"), data_(data), size_(size) {}
    bool read(char c[], int n) override
    {
        if (n < 0 || pos_ + static_cast<size_t>(n) > size_) throw std::runtime_error("unexpected end of file");
        std::memcpy(c, data_ + pos_, static_cast<size_t>(n));
        pos_ += static_cast<size_t>(n);
        return pos_ < size_;
    }
    uint64_t tellg() override { return pos_; }
    void seekg(uint64_t pos) override
    {
        if (pos > size_) throw std::runtime_error("seek past the end of the file");
        pos_ = static_cast<size_t>(pos);
    }
    void clear() override {}

  private:
    const char *data_;
    size_t size_, pos_ = 0;
};

}   // namespace

extern "C" int rs_exr_cxx_read(const void *data, size_t size, const char *const *names, int nnames, int x0, int y0,
                               int width, int height, float *out, char *msg, size_t msg_size)
{
    try {
        MemoryStream stream(static_cast<const char *>(data), size);
        Imf::InputFile file(stream);
        const Imath::Box2i dw = file.header().dataWindow();
        const long dw_w = static_cast<long>(dw.max.x) - dw.min.x + 1, dw_h = static_cast<long>(dw.max.y) - dw.min.y + 1;
        if (dw_w <= 0 || dw_h <= 0 || dw_w * dw_h > (1L << 27)) throw std::runtime_error("bad data window");
        std::vector<float> tmp(static_cast<size_t>(dw_w * dw_h) * static_cast<size_t>(nnames), 0.0f);
        Imf::FrameBuffer fb;
        const size_t xs = sizeof(float) * static_cast<size_t>(nnames), ys = xs * static_cast<size_t>(dw_w);
        for (int k = 0; k < nnames; k++) {
            if (!file.header().channels().findChannel(names[k])) throw std::runtime_error("channel missing");
            // Slice base so that pixel (dw.min.x, dw.min.y) lands at tmp[k]. It lies outside tmp
            // whenever the window does not start at 0, so it is computed on integers: pointer
            // arithmetic out of the object is undefined (UBSan, found by fuzz_image).
            const ptrdiff_t off = static_cast<ptrdiff_t>(dw.min.x) * static_cast<ptrdiff_t>(xs) +
                static_cast<ptrdiff_t>(dw.min.y) * static_cast<ptrdiff_t>(ys);
            char *base =
                reinterpret_cast<char *>(reinterpret_cast<uintptr_t>(tmp.data() + k) - static_cast<uintptr_t>(off));
            fb.insert(names[k], Imf::Slice(Imf::FLOAT, base, xs, ys));
        }
        file.setFrameBuffer(fb);
        file.readPixels(dw.min.y, dw.max.y);
        for (long y = std::max<long>(dw.min.y, y0); y <= std::min<long>(dw.max.y, y0 + height - 1L); y++)
            for (long x = std::max<long>(dw.min.x, x0); x <= std::min<long>(dw.max.x, x0 + width - 1L); x++)
                std::memcpy(out + ((y - y0) * width + (x - x0)) * nnames,
                            tmp.data() + ((y - dw.min.y) * dw_w + (x - dw.min.x)) * nnames, xs);
        return 0;
    } catch (const std::exception &e) {
        std::snprintf(msg, msg_size, "%s", e.what());
    } catch (...) {
        std::snprintf(msg, msg_size, "unknown error in OpenEXR's C++ library");
    }
    return -1;
}

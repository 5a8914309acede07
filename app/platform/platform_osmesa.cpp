// Headless GL 4.5 core context through OSMesa (Mesa's off-screen interface; llvmpipe).
#include "platform/platform.h"

#include "core/core.h"

#include <GL/osmesa.h>

#include <algorithm>
#include <cstring>
#include <string>

namespace fulgur::platform {

namespace {

class OSMesaContextImpl final : public Context {
public:
    explicit OSMesaContextImpl(const ContextOptions& o) : format_(o.format) {
        if (o.width <= 0 || o.height <= 0)
            throw core::Error("headless context",
                              "size must be positive, got " + std::to_string(o.width) + "x" + std::to_string(o.height));
        // No depth/stencil/accum in the default framebuffer: the renderer draws into its
        // own framebuffer objects and composites into this one with a full-screen pass.
        const int attribs[] = {OSMESA_FORMAT,
                               OSMESA_RGBA,
                               OSMESA_DEPTH_BITS,
                               0,
                               OSMESA_STENCIL_BITS,
                               0,
                               OSMESA_ACCUM_BITS,
                               0,
                               OSMESA_PROFILE,
                               OSMESA_CORE_PROFILE,
                               OSMESA_CONTEXT_MAJOR_VERSION,
                               4,
                               OSMESA_CONTEXT_MINOR_VERSION,
                               5,
                               0};
        ctx_ = OSMesaCreateContextAttribs(attribs, nullptr);
        if (!ctx_)
            throw core::Error("OSMesa",
                              "OSMesaCreateContextAttribs failed to create a GL 4.5 core context "
                              "(Mesa with llvmpipe >= 20 is required)");
        allocate(o.width, o.height);
        make_current();
        glFinish_ = reinterpret_cast<void (*)()>(OSMesaGetProcAddress("glFinish"));
        auto get_string = reinterpret_cast<const unsigned char* (*)(unsigned)>(OSMesaGetProcAddress("glGetString"));
        if (!glFinish_ || !get_string) throw core::Error("OSMesa", "no glFinish/glGetString in the context");
        const unsigned kRenderer = 0x1F01, kVersion = 0x1F02;  // GL_RENDERER, GL_VERSION
        description_ = std::string(reinterpret_cast<const char*>(get_string(kRenderer))) + " | " +
                       reinterpret_cast<const char*>(get_string(kVersion));
    }
    ~OSMesaContextImpl() override {
        if (ctx_) OSMesaDestroyContext(ctx_);
    }

    GetProcAddress get_proc_address() const override { return &OSMesaGetProcAddress; }

    void make_current() override {
        const GLenum type = format_ == PixelFormat::RGBA8 ? GL_UNSIGNED_BYTE : GL_FLOAT;
        void* buf =
            format_ == PixelFormat::RGBA8 ? static_cast<void*>(bytes_.data()) : static_cast<void*>(floats_.data());
        if (!OSMesaMakeCurrent(ctx_, buf, type, width_, height_))
            throw core::Error("OSMesa", "OSMesaMakeCurrent failed for a " + std::to_string(width_) + "x" +
                                            std::to_string(height_) + " buffer");
    }

    void present() override { glFinish_(); }
    int width() const override { return width_; }
    int height() const override { return height_; }

    void resize(int w, int h) override {
        if (w <= 0 || h <= 0)
            throw core::Error("headless context",
                              "size must be positive, got " + std::to_string(w) + "x" + std::to_string(h));
        allocate(w, h);
        make_current();
    }

    std::vector<std::uint8_t> read_rgba8() override {
        glFinish_();
        std::vector<std::uint8_t> out(std::size_t(width_) * std::size_t(height_) * 4);
        const std::size_t row = std::size_t(width_) * 4;
        for (int y = 0; y < height_; ++y) {  // OSMesa rows are bottom-up (OSMESA_Y_UP)
            const std::size_t src = std::size_t(height_ - 1 - y) * row, dst = std::size_t(y) * row;
            if (format_ == PixelFormat::RGBA8) {
                std::memcpy(out.data() + dst, bytes_.data() + src, row);
            } else {
                for (std::size_t i = 0; i < row; ++i) {
                    const float v = std::clamp(floats_[src + i], 0.0f, 1.0f);
                    out[dst + i] = std::uint8_t(v * 255.0f + 0.5f);
                }
            }
        }
        return out;
    }

    std::vector<float> read_rgba32f() override {
        glFinish_();
        std::vector<float> out(std::size_t(width_) * std::size_t(height_) * 4);
        const std::size_t row = std::size_t(width_) * 4;
        for (int y = 0; y < height_; ++y) {
            const std::size_t src = std::size_t(height_ - 1 - y) * row, dst = std::size_t(y) * row;
            for (std::size_t i = 0; i < row; ++i)
                out[dst + i] = format_ == PixelFormat::RGBA8 ? float(bytes_[src + i]) / 255.0f : floats_[src + i];
        }
        return out;
    }

    bool poll_events() override { return true; }
    const InputState& input() const override { return input_; }
    bool headless() const override { return true; }
    void* native_window() const override { return nullptr; }
    std::string description() const override { return description_; }

private:
    void allocate(int w, int h) {
        width_ = w;
        height_ = h;
        const std::size_t n = std::size_t(w) * std::size_t(h) * 4;
        if (format_ == PixelFormat::RGBA8)
            bytes_.assign(n, 0);
        else
            floats_.assign(n, 0.0f);
    }

    OSMesaContext ctx_ = nullptr;
    PixelFormat format_;
    int width_ = 0, height_ = 0;
    std::vector<std::uint8_t> bytes_;
    std::vector<float> floats_;
    void (*glFinish_)() = nullptr;
    InputState input_;
    std::string description_;
};

}  // namespace

std::unique_ptr<Context> create_headless(const ContextOptions& options) {
    return std::make_unique<OSMesaContextImpl>(options);
}

}  // namespace fulgur::platform

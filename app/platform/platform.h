// fulgur::platform — where an OpenGL context comes from. The one place that knows about
// window systems: the engine never includes GLFW or OSMesa; it receives a current context
// and its get-proc-address from here.
//
// Two implementations behind one interface:
//   * headless (OSMesa): an off-screen RGBA8 or RGBA float buffer in memory with a GL 4.5
//     core context (Mesa llvmpipe); used by tests, benchmarks and fulgur-shot;
//   * window (GLFW): a window with a GL 4.5 core context, vsync off; used by the demo.
//
// Usage:
//   auto ctx = platform::create_headless({.width = 640, .height = 360});
//   render::Renderer r(ctx->get_proc_address());   // context is current after creation
//   r.render(...);                                 // draws into framebuffer 0
//   auto rgba = ctx->read_rgba8();                 // top row first
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace fulgur::platform {

/// A GL function pointer and the get-proc-address of a context (same signatures as
/// glad's GLADapiproc / GLADloadfunc, so it can be passed to the renderer directly).
using GLProc = void (*)();
using GetProcAddress = GLProc (*)(const char* name);

/// Pixel format of a headless context's default framebuffer.
enum class PixelFormat { RGBA8, RGBA32F };

struct ContextOptions {
    int width = 640;  ///< framebuffer size in pixels (window: initial client size)
    int height = 360;
    PixelFormat format = PixelFormat::RGBA8;  ///< headless only
    std::string title = "Fulgur";             ///< window only
    bool visible = true;                      ///< window only
    bool vsync = false;                       ///< window only (off: measure real frame times)
};

/// Input collected by poll_events() (window contexts; headless contexts report nothing).
struct InputState {
    double cursor_x = 0, cursor_y = 0;        ///< pixels, origin top-left
    bool buttons[3] = {false, false, false};  ///< left, right, middle
    double scroll = 0;                        ///< wheel steps since the previous poll
    std::vector<int> keys_pressed;            ///< key codes pressed since the previous poll (GLFW_KEY_*)
    bool close_requested = false;
};

class Context {
public:
    virtual ~Context() = default;
    Context() = default;
    Context(const Context&) = delete;
    Context& operator=(const Context&) = delete;

    /// Loader entry point of this context (valid while the context is current).
    virtual GetProcAddress get_proc_address() const = 0;
    /// Makes this context current on the calling thread (done on creation too).
    virtual void make_current() = 0;
    /// Window: swaps buffers. Headless: glFinish (the buffer then holds the frame).
    virtual void present() = 0;
    /// Framebuffer size in pixels (a window's may change; check after poll_events()).
    virtual int width() const = 0;
    virtual int height() const = 0;
    /// Headless: reallocates the buffer. Window: resizes the window.
    virtual void resize(int width, int height) = 0;
    /// Reads the default framebuffer (the back buffer of a window: call before present()),
    /// rows top to bottom, 4 bytes per pixel.
    virtual std::vector<std::uint8_t> read_rgba8() = 0;
    /// Same, as floats (a float headless buffer keeps values outside [0, 1]).
    virtual std::vector<float> read_rgba32f() = 0;
    /// Processes window events; returns false once the window should close.
    virtual bool poll_events() = 0;
    virtual const InputState& input() const = 0;
    virtual bool headless() const = 0;
    /// GLFWwindow* for a window (for the ImGui GLFW backend), nullptr when headless.
    virtual void* native_window() const = 0;
    /// "llvmpipe (LLVM 15.0.6, 256 bits) | 4.5 (Core Profile) Mesa 22.3.6"
    virtual std::string description() const = 0;
};

/// Off-screen GL 4.5 core context through OSMesa. Throws core::Error when OSMesa cannot
/// create it (e.g. no GL 4.5 support), naming what failed.
std::unique_ptr<Context> create_headless(const ContextOptions& options = {});

/// True when a window system is reachable (GLFW initializes, i.e. an X display exists).
bool display_available();

/// A GLFW window with a GL 4.5 core context, current on return. Throws core::Error when
/// there is no display or the context cannot be created.
std::unique_ptr<Context> create_window(const ContextOptions& options = {});

}  // namespace fulgur::platform

// Window with a GL 4.5 core context through GLFW (X11/GLX; Xvfb works), vsync off.
#include "platform/platform.h"

#include "core/core.h"

#include <glad/gl.h>
#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include <cstring>
#include <string>

namespace fulgur::platform {

namespace {

std::string& last_glfw_error() {
    static std::string e;
    return e;
}

void on_glfw_error(int code, const char* what) {
    last_glfw_error() = std::string(what ? what : "unknown") + " (GLFW error " + std::to_string(code) + ")";
}

int& glfw_users() {
    static int n = 0;
    return n;
}

bool glfw_acquire() {
    glfwSetErrorCallback(&on_glfw_error);
    if (glfw_users() == 0 && !glfwInit()) return false;
    ++glfw_users();
    return true;
}

void glfw_release() {
    if (--glfw_users() == 0) glfwTerminate();
}

GLProc glfw_get_proc(const char* name) { return glfwGetProcAddress(name); }

class GlfwContext final : public Context {
public:
    explicit GlfwContext(const ContextOptions& o) {
        if (o.width <= 0 || o.height <= 0)
            throw core::Error("window",
                              "size must be positive, got " + std::to_string(o.width) + "x" + std::to_string(o.height));
        if (!glfw_acquire())
            throw core::Error("window", "no display: GLFW could not initialize (" + last_glfw_error() +
                                            "); set DISPLAY or use the headless mode");
        glfwDefaultWindowHints();
        glfwWindowHint(GLFW_CONTEXT_VERSION_MAJOR, 4);
        glfwWindowHint(GLFW_CONTEXT_VERSION_MINOR, 5);
        glfwWindowHint(GLFW_OPENGL_PROFILE, GLFW_OPENGL_CORE_PROFILE);
        glfwWindowHint(GLFW_OPENGL_FORWARD_COMPAT, GLFW_TRUE);
        glfwWindowHint(GLFW_DEPTH_BITS, 0);
        glfwWindowHint(GLFW_STENCIL_BITS, 0);
        glfwWindowHint(GLFW_VISIBLE, o.visible ? GLFW_TRUE : GLFW_FALSE);
        window_ = glfwCreateWindow(o.width, o.height, o.title.c_str(), nullptr, nullptr);
        if (!window_) {
            glfw_release();
            throw core::Error("window", "cannot create a window with a GL 4.5 core context: " + last_glfw_error());
        }
        glfwSetWindowUserPointer(window_, this);
        glfwSetScrollCallback(window_, [](GLFWwindow* w, double, double dy) {
            static_cast<GlfwContext*>(glfwGetWindowUserPointer(w))->input_.scroll += dy;
        });
        glfwSetKeyCallback(window_, [](GLFWwindow* w, int key, int, int action, int) {
            if (action == GLFW_PRESS)
                static_cast<GlfwContext*>(glfwGetWindowUserPointer(w))->input_.keys_pressed.push_back(key);
        });
        make_current();
        glfwSwapInterval(o.vsync ? 1 : 0);
        if (!gladLoadGL(&glfw_get_proc)) {
            glfwDestroyWindow(window_);
            glfw_release();
            throw core::Error("window", "cannot load OpenGL 4.5 core functions from the window's context");
        }
        description_ = std::string(reinterpret_cast<const char*>(glGetString(GL_RENDERER))) + " | " +
                       reinterpret_cast<const char*>(glGetString(GL_VERSION));
    }
    ~GlfwContext() override {
        glfwDestroyWindow(window_);
        glfw_release();
    }

    GetProcAddress get_proc_address() const override { return &glfw_get_proc; }
    void make_current() override { glfwMakeContextCurrent(window_); }
    void present() override { glfwSwapBuffers(window_); }
    int width() const override {
        int w = 0, h = 0;
        glfwGetFramebufferSize(window_, &w, &h);
        return w;
    }
    int height() const override {
        int w = 0, h = 0;
        glfwGetFramebufferSize(window_, &w, &h);
        return h;
    }
    void resize(int w, int h) override { glfwSetWindowSize(window_, w, h); }

    std::vector<std::uint8_t> read_rgba8() override {
        const int w = width(), h = height();
        std::vector<std::uint8_t> bottom_up(std::size_t(w) * std::size_t(h) * 4), out(bottom_up.size());
        read(GL_UNSIGNED_BYTE, bottom_up.data(), w, h);
        flip(bottom_up.data(), out.data(), std::size_t(w) * 4, h);
        return out;
    }
    std::vector<float> read_rgba32f() override {
        const int w = width(), h = height();
        std::vector<float> bottom_up(std::size_t(w) * std::size_t(h) * 4), out(bottom_up.size());
        read(GL_FLOAT, bottom_up.data(), w, h);
        flip(bottom_up.data(), out.data(), std::size_t(w) * 4, h);
        return out;
    }

    bool poll_events() override {
        input_.keys_pressed.clear();
        input_.scroll = 0;
        glfwPollEvents();
        glfwGetCursorPos(window_, &input_.cursor_x, &input_.cursor_y);
        input_.buttons[0] = glfwGetMouseButton(window_, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS;
        input_.buttons[1] = glfwGetMouseButton(window_, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS;
        input_.buttons[2] = glfwGetMouseButton(window_, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS;
        input_.close_requested = glfwWindowShouldClose(window_) != 0;
        return !input_.close_requested;
    }
    const InputState& input() const override { return input_; }
    bool headless() const override { return false; }
    void* native_window() const override { return window_; }
    std::string description() const override { return description_; }

private:
    void read(GLenum type, void* dst, int w, int h) {
        GLint fbo = 0;
        glGetIntegerv(GL_READ_FRAMEBUFFER_BINDING, &fbo);
        glBindFramebuffer(GL_READ_FRAMEBUFFER, 0);
        glReadBuffer(GL_BACK);
        glPixelStorei(GL_PACK_ALIGNMENT, 1);
        glReadPixels(0, 0, w, h, GL_RGBA, type, dst);
        glBindFramebuffer(GL_READ_FRAMEBUFFER, GLuint(fbo));
    }
    template <class T>
    static void flip(const T* src, T* dst, std::size_t row, int h) {
        for (int y = 0; y < h; ++y)
            std::memcpy(dst + std::size_t(y) * row, src + std::size_t(h - 1 - y) * row, row * sizeof(T));
    }

    GLFWwindow* window_ = nullptr;
    InputState input_;
    std::string description_;
};

}  // namespace

bool display_available() {
    if (!glfw_acquire()) return false;
    glfw_release();
    return true;
}

std::unique_ptr<Context> create_window(const ContextOptions& options) { return std::make_unique<GlfwContext>(options); }

}  // namespace fulgur::platform

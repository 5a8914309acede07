#include "demo/shell.h"

#include "core/core.h"

#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

namespace fulgur::app {

DemoShell::DemoShell(int width, int height, const std::string& title, int screenshot_after)
    : screenshot_after_(screenshot_after) {
    ctx_ = platform::create_window({.width = width, .height = height, .title = title});
    win_ = static_cast<GLFWwindow*>(ctx_->native_window());
    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;
    ImGui_ImplGlfw_InitForOpenGL(win_, true);
    ImGui_ImplOpenGL3_Init("#version 450");
    last_ = glfwGetTime();
    glfwGetCursorPos(win_, &mx_, &my_);
}

DemoShell::~DemoShell() {
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
}

bool DemoShell::begin_frame(Orbit& orbit) {
    glfwPollEvents();
    if (glfwWindowShouldClose(win_)) return false;
    const double now = glfwGetTime();
    dt_ = std::max(now - last_, 1e-6);
    last_ = now;
    recent_.push_back(dt_);
    recent_sum_ += dt_;
    while (recent_.size() > 1 && recent_sum_ - recent_.front() >= 1.0) {
        recent_sum_ -= recent_.front();
        recent_.pop_front();
    }
    fps_ = double(recent_.size()) / recent_sum_;

    const ImGuiIO& io = ImGui::GetIO();
    double cx, cy;
    glfwGetCursorPos(win_, &cx, &cy);
    if (!io.WantCaptureMouse) {
        if (glfwGetMouseButton(win_, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS) {
            orbit.turn(-0.3 * (cx - mx_));
            orbit.el = std::clamp(orbit.el + 0.3 * (cy - my_), -89.0, 89.0);
        }
        if (io.MouseWheel != 0)
            orbit.dist = std::clamp(orbit.dist * std::pow(0.9, io.MouseWheel), orbit.dist_min, orbit.dist_max);
    }
    mx_ = cx, my_ = cy;

    strike_ = camera_ = false;
    if (!io.WantCaptureKeyboard) {
        const bool sp = glfwGetKey(win_, GLFW_KEY_SPACE) == GLFW_PRESS, pk = glfwGetKey(win_, GLFW_KEY_P) == GLFW_PRESS,
                   ck = glfwGetKey(win_, GLFW_KEY_C) == GLFW_PRESS, hk = glfwGetKey(win_, GLFW_KEY_H) == GLFW_PRESS;
        strike_ = sp && !space_down_;
        camera_ = ck && !c_down_;
        if (pk && !p_down_) screenshot_ = true;
        if (hk && !h_down_) panels_ = !panels_;
        space_down_ = sp, p_down_ = pk, c_down_ = ck, h_down_ = hk;
        if (glfwGetKey(win_, GLFW_KEY_ESCAPE) == GLFW_PRESS) glfwSetWindowShouldClose(win_, 1);
    }
    ImGui_ImplOpenGL3_NewFrame();
    ImGui_ImplGlfw_NewFrame();
    ImGui::NewFrame();
    return true;
}

bool DemoShell::end_frame() {
    ImGui::Render();
    ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
    ++frames_;
    if (screenshot_after_ > 0 && frames_ >= screenshot_after_ && !hold_ && !auto_shot_) {
        screenshot_ = true;
        auto_shot_ = true;
    }
    const bool shot = screenshot_;
    if (screenshot_) {
        screenshot_ = false;
        std::filesystem::create_directories("out");
        char name[64];
        std::snprintf(name, sizeof name, "out/screenshot_%03d.png", shots_++);
        core::write_png(name, ctx_->width(), ctx_->height(), 4, ctx_->read_rgba8());
        std::printf("wrote %s (%.1f fps over the last second)\n", name, fps_);
        if (screenshot_after_ > 0) glfwSetWindowShouldClose(win_, 1);
    }
    ctx_->present();
    return shot;
}

}  // namespace fulgur::app

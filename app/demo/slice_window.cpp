#include "demo/slice_window.h"

#include "core/core.h"

#include <GLFW/glfw3.h>
#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace fulgur::app {

struct SliceWindow::Gl {
    void (*GenTextures)(GLsizei, GLuint*);
    void (*BindTexture)(GLenum, GLuint);
    void (*TexParameteri)(GLenum, GLenum, GLint);
    void (*PixelStorei)(GLenum, GLint);
    void (*TexImage2D)(GLenum, GLint, GLint, GLsizei, GLsizei, GLint, GLenum, GLenum, const void*);
};

SliceWindow::SliceWindow() {
    auto g = std::make_unique<Gl>();
    g->GenTextures = reinterpret_cast<decltype(g->GenTextures)>(glfwGetProcAddress("glGenTextures"));
    g->BindTexture = reinterpret_cast<decltype(g->BindTexture)>(glfwGetProcAddress("glBindTexture"));
    g->TexParameteri = reinterpret_cast<decltype(g->TexParameteri)>(glfwGetProcAddress("glTexParameteri"));
    g->PixelStorei = reinterpret_cast<decltype(g->PixelStorei)>(glfwGetProcAddress("glPixelStorei"));
    g->TexImage2D = reinterpret_cast<decltype(g->TexImage2D)>(glfwGetProcAddress("glTexImage2D"));
    if (!g->GenTextures || !g->BindTexture || !g->TexParameteri || !g->PixelStorei || !g->TexImage2D)
        throw core::Error("fulgur", "the window's GL context lacks basic texture functions");
    GLuint tex = 0;
    g->GenTextures(1, &tex);
    texture_ = tex;
    gl_ = std::move(g);
}

SliceWindow::~SliceWindow() = default;

void SliceWindow::draw(const runtime::Frame* f, int width, int height) {
    if (!f || !f->lit || f->radiance.values.empty()) return;
    const core::GridGeometry& g = f->radiance.geometry;
    const std::vector<float>& v = f->radiance.values[0];
    // The x-z slice through the brightest cell (where the bolt lights the cloud).
    const int j = g.unindex(std::size_t(std::max_element(v.begin(), v.end()) - v.begin())).y;
    float vmax = 0;
    for (int k = 0; k < g.dims.z; ++k)
        for (int i = 0; i < g.dims.x; ++i) vmax = std::max(vmax, v[g.index(i, j, k)]);
    std::vector<std::uint8_t> img(std::size_t(g.dims.x) * g.dims.z * 4);
    for (int k = 0; k < g.dims.z; ++k)
        for (int i = 0; i < g.dims.x; ++i) {
            std::uint8_t* px = &img[(std::size_t(g.dims.z - 1 - k) * g.dims.x + i) * 4];
            core::pseudo_colour(vmax > 0 ? std::sqrt(v[g.index(i, j, k)] / vmax) : 0.0, px);
            px[3] = 255;
        }
    gl_->BindTexture(GL_TEXTURE_2D, texture_);
    gl_->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
    gl_->TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    gl_->PixelStorei(GL_UNPACK_ALIGNMENT, 1);
    gl_->TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, g.dims.x, g.dims.z, 0, GL_RGBA, GL_UNSIGNED_BYTE, img.data());
    const float wpx = 240.0f;
    ImGui::SetNextWindowPos({float(width) - 10.0f, float(height) - 10.0f}, ImGuiCond_FirstUseEver, {1.0f, 1.0f});
    ImGui::Begin("S: x-z slice through its maximum", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
    ImGui::Image((ImTextureID)(intptr_t)texture_, {wpx, wpx * g.dims.z / float(g.dims.x)});
    if (ImGui::IsItemHovered())
        ImGui::SetTooltip(
            "the reconstructed source function S (first direction), square-root scale,\n"
            "normalized to the slice's maximum: where the bolt lights the cloud");
    ImGui::End();
}

}  // namespace fulgur::app

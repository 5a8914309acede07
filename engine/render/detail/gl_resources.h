// Internal to fulgur::render: the GL objects the renderer owns (colour targets with their
// framebuffers, growable buffers, 3D textures) and the per-direction textures of a source
// function.
#pragma once

#include "core/core.h"

#include <glad/gl.h>

#include <glm/vec3.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <initializer_list>
#include <span>
#include <string>
#include <vector>

namespace fulgur::render::detail {

/// A single-level 3D texture of `format`, linearly filtered and clamped to its edges.
inline GLuint make_texture_3d(GLenum format, const core::Int3& dims) {
    GLuint t = 0;
    glCreateTextures(GL_TEXTURE_3D, 1, &t);
    glTextureStorage3D(t, 1, format, dims.x, dims.y, dims.z);
    glTextureParameteri(t, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(t, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(t, GL_TEXTURE_WRAP_S, GL_CLAMP_TO_EDGE);
    glTextureParameteri(t, GL_TEXTURE_WRAP_T, GL_CLAMP_TO_EDGE);
    glTextureParameteri(t, GL_TEXTURE_WRAP_R, GL_CLAMP_TO_EDGE);
    return t;
}

/// Deletes `t` (when it exists) and zeroes it.
inline void delete_texture(GLuint& t) {
    if (t) glDeleteTextures(1, &t);
    t = 0;
}

/// A w x h 2D texture of `format` (RGBA32F by default), linearly filtered, clamped to its edges
/// (GL_CLAMP_TO_BORDER as `wrap`: zero outside them, GL's default border colour).
inline GLuint make_texture_2d(int w, int h, GLenum format = GL_RGBA32F, GLenum wrap = GL_CLAMP_TO_EDGE) {
    GLuint tex = 0;
    glCreateTextures(GL_TEXTURE_2D, 1, &tex);
    glTextureStorage2D(tex, 1, format, w, h);
    glTextureParameteri(tex, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
    glTextureParameteri(tex, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTextureParameteri(tex, GL_TEXTURE_WRAP_S, GLint(wrap));
    glTextureParameteri(tex, GL_TEXTURE_WRAP_T, GLint(wrap));
    return tex;
}

/// Throws unless framebuffer `fbo` (w x h) is complete.
inline void check_framebuffer(GLuint fbo, int w, int h) {
    if (glCheckNamedFramebufferStatus(fbo, GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        throw core::Error("render",
                          "framebuffer of " + std::to_string(w) + "x" + std::to_string(h) + " is not complete");
}

/// Framebuffer `fbo` (created when 0) drawing into `textures` as its colour attachments 0, 1,
/// ... in that order (at most 8): a pass that writes several targets at once.
inline void attach_targets(GLuint& fbo, std::initializer_list<GLuint> textures) {
    if (!fbo) glCreateFramebuffers(1, &fbo);
    GLenum draw[8];
    GLsizei n = 0;
    for (const GLuint tex : textures) {
        draw[n] = GLenum(GL_COLOR_ATTACHMENT0 + n);
        glNamedFramebufferTexture(fbo, draw[n], tex, 0);
        ++n;
    }
    glNamedFramebufferDrawBuffers(fbo, n, draw);
}

struct Target {  // a colour texture (RGBA32F unless asked otherwise) + framebuffer
    GLuint tex = 0, fbo = 0;
    int w = 0, h = 0;
    GLenum format = GL_RGBA32F;
    void ensure(int width, int height, GLenum texture_format = GL_RGBA32F) {
        if (tex && w == width && h == height && format == texture_format) return;
        release();
        w = width;
        h = height;
        format = texture_format;
        tex = make_texture_2d(w, h, format);
        glCreateFramebuffers(1, &fbo);
        glNamedFramebufferTexture(fbo, GL_COLOR_ATTACHMENT0, tex, 0);
        check_framebuffer(fbo, w, h);
    }
    void release() {
        if (fbo) glDeleteFramebuffers(1, &fbo);
        delete_texture(tex);
        fbo = 0;
        w = h = 0;
    }
};

struct Buffer {
    GLuint id = 0;
    std::size_t capacity = 0;
    void upload(const void* data, std::size_t bytes) {
        if (bytes == 0) bytes = 16;  // never bind an empty buffer
        if (!id || capacity < bytes) {
            if (id) glDeleteBuffers(1, &id);
            glCreateBuffers(1, &id);
            capacity = std::max<std::size_t>(bytes, 1024);
            glNamedBufferData(id, GLsizeiptr(capacity), nullptr, GL_DYNAMIC_DRAW);
        }
        if (data) glNamedBufferSubData(id, 0, GLsizeiptr(bytes), data);
    }
    void release() {
        if (id) glDeleteBuffers(1, &id);
        id = 0;
        capacity = 0;
    }
};

/// The source function on a lighting grid, one 3D texture per baked direction, and its
/// resolve toward the camera: the flash's S (R32F) and the static light's (sun, moon, sky;
/// RGBA32F, colour). Only the directions listed by the latest upload are present.
struct SourceSet {
    explicit SourceSet(GLenum f) : format(f) {}
    GLenum format = GL_R32F;
    core::GridGeometry geom;
    int dir_count = 0;
    std::vector<GLuint> tex;  ///< per baked direction
    std::vector<bool> present;
    GLuint cam_tex = 0;  ///< S toward the camera (more than one direction)
    bool has = false;    ///< some direction is present
    bool dirty = true;   ///< S changed since the last resolve
    glm::dvec3 resolved_camera{std::nan("")};

    /// Textures for this grid and direction count (new ones, empty, when either changed).
    /// Returns true when it (re)allocated.
    bool ensure(const core::GridGeometry& g, int count) {
        if (geom == g && dir_count == count && !tex.empty()) return false;
        release();
        tex.assign(std::size_t(count), 0);
        for (GLuint& t : tex) t = make_texture_3d(format, g.dims);
        if (count > 1) {
            // The resolve writes only the tiles near the cloud; the rest stays zero (read by
            // the march only where the density is zero, so never NaN garbage).
            cam_tex = make_texture_3d(format, g.dims);
            glClearTexImage(cam_tex, 0, format == GL_R32F ? GL_RED : GL_RGBA, GL_FLOAT, nullptr);
        }
        geom = g;
        dir_count = count;
        return true;
    }
    void release() {
        for (GLuint& t : tex) delete_texture(t);
        tex.clear();
        delete_texture(cam_tex);
        present.clear();
        has = false;
        dirty = true;
        dir_count = 0;
    }
};

/// Validates an upload of `channels` floats per cell and writes it into `set` (see
/// SourceUpload: the listed directions replace the set, or are added with keep_others).
void upload_into(SourceSet& set, const char* what, const core::GridGeometry& geometry, int direction_count,
                 const std::vector<int>& directions, const std::vector<std::span<const float>>& values, int channels,
                 bool keep_others);

}  // namespace fulgur::render::detail

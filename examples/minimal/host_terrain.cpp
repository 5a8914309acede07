// The game's own world in fulgur-minimal (host_terrain.h): terrain mesh, shaders, HDR target and
// tone map, with plain OpenGL calls (OSMesa exports the GL 4.5 entry points; a windowed game
// would call them through its own loader).
#define GL_GLEXT_PROTOTYPES
#include "host_terrain.h"

#include <GL/gl.h>
#include <GL/glext.h>

#include <cmath>
#include <stdexcept>
#include <string>

namespace {

const char* kTerrainVert = R"(#version 450 core
layout(location = 0) in vec3 a_position;
layout(location = 1) in vec3 a_normal;
uniform mat4 u_view_proj;
out vec3 v_position, v_normal;
void main() {
    v_position = a_position;
    v_normal = a_normal;
    gl_Position = u_view_proj * vec4(a_position, 1.0);
})";

// Lambert: albedo / pi x irradiance, from the sky dome (radiance u_sky, the part of it a surface
// tilted by n sees) and the flash's point lights (I cos / r^2). Alpha: what the fragment is.
const char* kTerrainFrag = R"(#version 450 core
in vec3 v_position, v_normal;
uniform vec3 u_sky;
uniform float u_albedo;
uniform int u_light_count;
uniform vec3 u_light_position[8], u_light_intensity[8];
uniform vec2 u_origin, u_forward, u_front_back;
out vec4 o_radiance;
void main() {
    vec3 n = normalize(v_normal);
    vec3 e = 3.14159265 * u_sky * (0.5 + 0.5 * n.z);
    for (int i = 0; i < u_light_count; ++i) {
        vec3 d = u_light_position[i] - v_position;
        float r2 = dot(d, d);
        e += u_light_intensity[i] * max(dot(n, d), 0.0) * inversesqrt(r2) / r2;
    }
    float s = dot(v_position.xy - u_origin, u_forward);  // distance along the view
    float id = s < u_front_back.x ? 1.0 : (s > u_front_back.y ? 2.0 : 3.0);
    o_radiance = vec4(u_albedo / 3.14159265 * e, id);
})";

const char* kToneVert = R"(#version 450 core
void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
})";

const char* kToneFrag = R"(#version 450 core
uniform sampler2D u_hdr;
uniform float u_exposure;
out vec4 o_colour;
void main() {
    vec3 x = u_exposure * texelFetch(u_hdr, ivec2(gl_FragCoord.xy), 0).rgb;
    o_colour = vec4(pow(x / (1.0 + x), vec3(1.0 / 2.2)), 1.0);
})";

GLuint compile(GLenum stage, const char* source) {
    const GLuint s = glCreateShader(stage);
    glShaderSource(s, 1, &source, nullptr);
    glCompileShader(s);
    GLint ok = 0;
    glGetShaderiv(s, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        char log[2048];
        glGetShaderInfoLog(s, sizeof log, nullptr, log);
        throw std::runtime_error(std::string("host shader: ") + log);
    }
    return s;
}

GLuint link(const char* vert, const char* frag) {
    const GLuint p = glCreateProgram(), v = compile(GL_VERTEX_SHADER, vert), f = compile(GL_FRAGMENT_SHADER, frag);
    glAttachShader(p, v);
    glAttachShader(p, f);
    glLinkProgram(p);
    glDeleteShader(v);
    glDeleteShader(f);
    GLint ok = 0;
    glGetProgramiv(p, GL_LINK_STATUS, &ok);
    if (!ok) throw std::runtime_error("host shader: link failed");
    return p;
}

double bump(double u, double v) { return std::exp(-u * u - v * v); }

}  // namespace

HostWorld::HostWorld(int width, int height, const TerrainLayout& l) : width_(width), height_(height) {
    // The terrain in view coordinates: s metres ahead of the camera (horizontally), q to its right.
    const glm::dvec2 cam(l.camera), fwd = glm::normalize(glm::dvec2(l.storm_centre) - cam), right(fwd.y, -fwd.x);
    const double storm = glm::dot(glm::dvec2(l.storm_centre) - cam, fwd), r = l.storm_radius;
    const double flash_s = glm::dot(glm::dvec2(l.flash) - cam, fwd),
                 flash_q = glm::dot(glm::dvec2(l.flash) - cam, right);
    const double ridge_s = 0.8 * (storm - r), range_s = storm + r + 2000.0;
    // The ridge's summit on the line of sight to the flash, reaching 400 m above it there.
    const double peak_q = flash_q * ridge_s / flash_s,
                 peak_h = l.camera.z + (l.flash.z + 400.0 - l.camera.z) * ridge_s / flash_s;
    auto elevation = [&](double s, double q) {
        const double ridge = peak_h *
                             (0.3 + 0.25 * bump((q - peak_q) / 6000.0, 0.0) + 0.45 * bump((q - peak_q) / 1200.0, 0.0)) *
                             bump((s - ridge_s) / 1300.0, 0.0);
        const double peaks[7][2] = {{-24e3, 3200}, {-15e3, 4200}, {-7e3, 2800}, {0, 3800},
                                    {8e3, 4500},   {16e3, 3000},  {25e3, 3600}};
        double range = s > range_s ? 700.0 * (1.0 - std::exp(-(s - range_s) / 3000.0)) : 0.0;
        for (int i = 0; i < 7; ++i)
            range += peaks[i][1] * bump((q - peaks[i][0]) / 3000.0, (s - range_s - 1500.0 * (i % 3)) / 4000.0);
        range *= 1.0 + 0.12 * std::sin(q / 1900.0 + s / 2700.0);  // rougher flanks
        return 100.0 + 80.0 * std::sin(s / 2100.0) * std::sin(q / 1300.0) + std::max(ridge, range);
    };
    // A 128 x 128 grid from 500 m ahead to 15 km past the range, finer near the camera.
    constexpr int n = 128;
    const double s_far = range_s + 15000.0, q_half = 0.9 * s_far;
    std::vector<float> vertices;
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
            const double s = 500.0 + (s_far - 500.0) * std::pow(j / double(n - 1), 1.4);
            const double q = q_half * (2.0 * i / double(n - 1) - 1.0), h = 10.0;  // h: finite-difference step
            const glm::dvec2 xy = cam + s * fwd + q * right;
            const double ds = (elevation(s + h, q) - elevation(s - h, q)) / (2 * h);
            const double dq = (elevation(s, q + h) - elevation(s, q - h)) / (2 * h);
            const glm::dvec2 grad = ds * fwd + dq * right;  // dz/dx, dz/dy in world axes
            const glm::dvec3 normal = glm::normalize(glm::dvec3(-grad.x, -grad.y, 1.0));
            for (double v : {xy.x, xy.y, elevation(s, q), normal.x, normal.y, normal.z}) vertices.push_back(float(v));
        }
    std::vector<unsigned> indices;
    for (int j = 0; j + 1 < n; ++j)
        for (int i = 0; i + 1 < n; ++i) {
            const unsigned a = unsigned(j * n + i), b = a + 1, c = a + n, d = c + 1;
            for (unsigned k : {a, b, d, a, d, c}) indices.push_back(k);
        }
    index_count_ = int(indices.size());
    front_back_ = glm::vec2(float(storm - r), float(storm + r));
    forward_ = glm::vec2(fwd);
    origin_ = glm::vec2(cam);

    glGenVertexArrays(1, &vao_);
    glBindVertexArray(vao_);
    glGenBuffers(1, &vbo_);
    glBindBuffer(GL_ARRAY_BUFFER, vbo_);
    glBufferData(GL_ARRAY_BUFFER, GLsizeiptr(vertices.size() * sizeof(float)), vertices.data(), GL_STATIC_DRAW);
    glGenBuffers(1, &ibo_);
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, ibo_);
    glBufferData(GL_ELEMENT_ARRAY_BUFFER, GLsizeiptr(indices.size() * sizeof(unsigned)), indices.data(),
                 GL_STATIC_DRAW);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), nullptr);
    glVertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, 6 * sizeof(float), reinterpret_cast<void*>(3 * sizeof(float)));
    glEnableVertexAttribArray(0);
    glEnableVertexAttribArray(1);
    glBindVertexArray(0);
    terrain_program_ = link(kTerrainVert, kTerrainFrag);
    tone_program_ = link(kToneVert, kToneFrag);

    // The HDR target: float radiance (the channel's core reaches 1e4 W m^-2 sr^-1) and a depth texture.
    glGenTextures(1, &colour_);
    glBindTexture(GL_TEXTURE_2D, colour_);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, width, height, 0, GL_RGBA, GL_FLOAT, nullptr);
    glGenTextures(1, &depth_);
    glBindTexture(GL_TEXTURE_2D, depth_);
    glTexImage2D(GL_TEXTURE_2D, 0, GL_DEPTH_COMPONENT32F, width, height, 0, GL_DEPTH_COMPONENT, GL_FLOAT, nullptr);
    for (GLuint t : {colour_, depth_}) {
        glBindTexture(GL_TEXTURE_2D, t);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
    }
    glBindTexture(GL_TEXTURE_2D, 0);
    glGenFramebuffers(1, &fbo_);
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, colour_, 0);
    glFramebufferTexture2D(GL_FRAMEBUFFER, GL_DEPTH_ATTACHMENT, GL_TEXTURE_2D, depth_, 0);
    if (glCheckFramebufferStatus(GL_FRAMEBUFFER) != GL_FRAMEBUFFER_COMPLETE)
        throw std::runtime_error("host: the HDR framebuffer is incomplete");
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
}

HostWorld::~HostWorld() {
    glDeleteFramebuffers(1, &fbo_);
    glDeleteTextures(1, &colour_);
    glDeleteTextures(1, &depth_);
    glDeleteBuffers(1, &vbo_);
    glDeleteBuffers(1, &ibo_);
    glDeleteVertexArrays(1, &vao_);
    glDeleteProgram(terrain_program_);
    glDeleteProgram(tone_program_);
}

void HostWorld::draw_terrain(const glm::mat4& view_proj, const std::vector<FlashLight>& lights) {
    glBindFramebuffer(GL_FRAMEBUFFER, fbo_);
    glViewport(0, 0, width_, height_);
    const glm::vec3 sky(6e-4f, 7e-4f, 9e-4f);  // a night sky lit by a distant town (W m^-2 sr^-1)
    const float clear[4] = {sky.r, sky.g, sky.b, kSky}, far = 1.0f;
    glClearBufferfv(GL_COLOR, 0, clear);
    glClearBufferfv(GL_DEPTH, 0, &far);
    glEnable(GL_DEPTH_TEST);
    glDepthFunc(GL_LESS);
    glUseProgram(terrain_program_);
    auto at = [&](const char* name) { return glGetUniformLocation(terrain_program_, name); };
    glUniformMatrix4fv(at("u_view_proj"), 1, GL_FALSE, &view_proj[0][0]);
    glUniform3fv(at("u_sky"), 1, &sky[0]);
    glUniform1f(at("u_albedo"), 0.4f);  // rock and old snow
    const int count = int(std::min<std::size_t>(lights.size(), 8));
    glUniform1i(at("u_light_count"), count);
    for (int i = 0; i < count; ++i) {
        const std::string k = "[" + std::to_string(i) + "]";
        glUniform3fv(at(("u_light_position" + k).c_str()), 1, &lights[std::size_t(i)].position[0]);
        glUniform3fv(at(("u_light_intensity" + k).c_str()), 1, &lights[std::size_t(i)].intensity[0]);
    }
    glUniform2fv(at("u_origin"), 1, &origin_[0]);
    glUniform2fv(at("u_forward"), 1, &forward_[0]);
    glUniform2fv(at("u_front_back"), 1, &front_back_[0]);
    glBindVertexArray(vao_);
    glDrawElements(GL_TRIANGLES, index_count_, GL_UNSIGNED_INT, nullptr);
    glBindVertexArray(0);
    glDisable(GL_DEPTH_TEST);
    // The target stays bound: the storm is composited into it next.
}

std::vector<float> HostWorld::read() const {
    std::vector<float> rgba(std::size_t(width_) * std::size_t(height_) * 4);
    glBindFramebuffer(GL_READ_FRAMEBUFFER, fbo_);
    glReadPixels(0, 0, width_, height_, GL_RGBA, GL_FLOAT, rgba.data());
    return rgba;
}

void HostWorld::tone_map(float exposure) {
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    glViewport(0, 0, width_, height_);
    glUseProgram(tone_program_);
    glUniform1f(glGetUniformLocation(tone_program_, "u_exposure"), exposure);
    glActiveTexture(GL_TEXTURE0);
    glBindTexture(GL_TEXTURE_2D, colour_);
    glUniform1i(glGetUniformLocation(tone_program_, "u_hdr"), 0);
    glBindVertexArray(vao_);
    glDrawArrays(GL_TRIANGLES, 0, 3);
    glBindVertexArray(0);
    glBindTexture(GL_TEXTURE_2D, 0);
}

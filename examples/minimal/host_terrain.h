// The game's own world in fulgur-minimal: what a host engine draws itself before it hands its
// frame to Fulgur. A heightfield around the storm (a ridge between the camera and the storm, a
// range behind it) drawn with its own shader (Lambert: a dim night sky plus the flash's point
// lights with 1/r^2 falloff) into its own HDR target (RGBA32F colour + 32-bit float depth
// texture), and its own tone map into the default framebuffer.
#pragma once

#include <glm/glm.hpp>

#include <vector>

/// A point light of the flash: position (m) and radiant intensity per channel (W/sr).
struct FlashLight {
    glm::vec3 position;
    glm::vec3 intensity;
};

/// Where the terrain's features go (world metres, z up): the ridge stands in front of the flash
/// as the camera sees it, its peak reaching the line of sight to the flash's centre (so it hides
/// the lower part of the channel); the range rises behind the storm.
struct TerrainLayout {
    glm::dvec3 camera, storm_centre, flash;
    double storm_radius = 0.0;
};

class HostWorld {
public:
    /// What the terrain's fragments are, in the target's alpha (render_into_host keeps it): the
    /// ridge and the ground before it (in front of the storm), the range behind the storm, the
    /// ground under the storm.
    static constexpr float kSky = 0.0f, kRidge = 1.0f, kRange = 2.0f, kGround = 3.0f;

    /// Builds the mesh, the shaders and the target; a GL 4.5 core context must be current.
    HostWorld(int width, int height, const TerrainLayout& layout);
    ~HostWorld();
    HostWorld(const HostWorld&) = delete;
    HostWorld& operator=(const HostWorld&) = delete;

    unsigned framebuffer() const { return fbo_; }
    unsigned depth_texture() const { return depth_; }
    /// Clears the target to the night sky and draws the terrain (depth tested and written).
    void draw_terrain(const glm::mat4& view_proj, const std::vector<FlashLight>& lights);
    /// The HDR target: RGBA floats, bottom row first (alpha: kSky, kRidge, kRange or kGround).
    std::vector<float> read() const;
    /// exposure x / (1 + exposure x) per channel, sRGB-encoded, into the default framebuffer.
    void tone_map(float exposure);

private:
    int width_, height_;
    unsigned fbo_ = 0, colour_ = 0, depth_ = 0;
    unsigned vao_ = 0, vbo_ = 0, ibo_ = 0, terrain_program_ = 0, tone_program_ = 0;
    int index_count_ = 0;
    glm::vec2 front_back_{0.0f};  // the storm's front and back along the view (m from the camera)
    glm::vec2 forward_{0.0f};     // horizontal view direction
    glm::vec2 origin_{0.0f};      // the camera's x, y
};

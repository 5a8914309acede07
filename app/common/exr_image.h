// OpenEXR images of linear radiance (fulgur-shot --exr): float32 layers, the camera and the
// units in the header; and the reader the tests and tools check them with.
#pragma once

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <span>
#include <string>
#include <utility>
#include <vector>

namespace fulgur::app {

/// Channels of one layer, interleaved, rows top to bottom. The layer "" holds the plain
/// channels ("R", "G", "B"); another layer's channels are stored as "<layer>.<channel>".
struct ExrLayer {
    std::string name;
    std::vector<std::string> channels;
    std::vector<float> values;  ///< width * height * channels.size()
};

/// Header attributes beside the standard ones.
struct ExrHeader {
    std::vector<std::pair<std::string, std::string>> text;
    std::vector<std::pair<std::string, double>> numbers;  ///< stored as double attributes
    std::vector<std::pair<std::string, glm::dvec3>> vectors;
    /// The standard worldToCamera / worldToNDC matrices (OpenEXR's ImfStandardAttributes).
    std::optional<glm::dmat4> world_to_camera, world_to_ndc;
};

/// Writes `path` atomically (core::AtomicFile), float32 channels, ZIP compression. Throws
/// core::Error naming the file (and the value) on non-finite values or a failed write.
void write_exr(const std::filesystem::path& path, int width, int height, std::span<const ExrLayer> layers,
               const ExrHeader& header);

/// A float image as read back: every channel by its full name ("R", "lightning.G"), rows top
/// to bottom, and the header's string and double attributes.
struct ExrImage {
    int width = 0, height = 0;
    std::map<std::string, std::vector<float>> channels;
    std::map<std::string, std::string> text;
    std::map<std::string, double> numbers;
    std::map<std::string, glm::dvec3> vectors;
};

/// Reads an EXR whose channels are float or half (converted), at most `max_pixels` pixels and
/// 64 channels, the file at most 4 GiB. Throws core::Error naming the file on anything else.
ExrImage read_exr(const std::filesystem::path& path, std::uint64_t max_pixels = std::uint64_t(1) << 26);

}  // namespace fulgur::app

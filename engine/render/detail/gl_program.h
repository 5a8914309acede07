// Internal: GLSL loading with #include, #line mapping of driver logs back to files, and
// program building. Tests include this header (preprocess/map_log need no GL context).
#pragma once

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

namespace fulgur::render::detail {

/// Each file of a preprocessed shader gets its own block of line numbers: line n of file k
/// is emitted as line k * kLineBase + n (via #line). Drivers report (source, line) pairs
/// with varying fidelity (Mesa ignores the source-string number of #line), but every driver
/// honours the line number, so the file is recovered from the line alone.
inline constexpr int kLineBase = 100000;

struct Preprocessed {
    std::string text;                ///< GLSL ready for glShaderSource
    std::vector<std::string> files;  ///< file k's display name (relative to the shader dir)
};

/// Reads `name` from `dir`, puts `defines` (lines "#define X V") right after its #version,
/// and expands `#include "other.glsl"` lines (relative to dir; each file at most once per
/// shader). Throws core::Error naming the file (and line) on a missing file, a missing
/// #version or a #version inside an included file.
Preprocessed preprocess(const std::filesystem::path& dir, const std::string& name, const std::string& defines = {});

struct MappedLog {
    std::string text;            ///< the log with locations rewritten as "file:line(col)"
    std::string first_location;  ///< "file:line" of the first located message ("" if none)
};

/// Rewrites the locations in a driver info log. Understands Mesa ("0:12(5): error"),
/// NVIDIA ("0(12) : error") and AMD/Intel ("ERROR: 0:12: ...") formats.
MappedLog map_log(const std::string& log, const std::vector<std::string>& files);

struct Stage {
    unsigned type;     ///< GL_VERTEX_SHADER, GL_FRAGMENT_SHADER, GL_COMPUTE_SHADER
    std::string file;  ///< file name in the shader directory
};

/// Compiles and links a program (GL must be loaded and a context current). Throws
/// core::Error: compile errors name "file:line" of the first error and carry the mapped log;
/// link errors name the program's files.
unsigned build_program(const std::filesystem::path& dir, const std::vector<Stage>& stages,
                       const std::string& defines = {});

}  // namespace fulgur::render::detail

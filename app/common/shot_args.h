// fulgur-shot's command line (kept apart from main so tests can check the validation).
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace fulgur::app {

struct ShotArgs {
    std::filesystem::path scene;
    std::optional<std::filesystem::path> fgb;  ///< default: the scene's up-to-date .fgb (baked if needed)
    std::uint64_t seed = 1;
    double time = 0.6;
    bool time_after_return_stroke = false;  ///< --time +T: T seconds after the first return stroke's onset
    int width = 640, height = 360;
    int repeat = 1;  ///< --repeat N: render N times, report medians (the first frame compiles shaders); same image
    double exposure_ev = 0.0;  ///< --exposure EV: exposure = 2^EV (render::Settings::exposure)
    std::filesystem::path output;
    /// --reference REF.png: also render the frame lit by the direct solve (the reference the
    /// basis method is measured against) into REF.png, its difference image into
    /// REF_diff.png, and print a second JSON line with the errors and the times.
    std::optional<std::filesystem::path> reference;
    bool help = false;
};

/// The --help text.
std::string shot_usage();

/// Parses argv[1..]. Throws core::Error with a one-line reason on any invalid input
/// (unknown option, missing value, malformed number, non-positive size, missing -o, two of
/// the images -o, REF.png, REF_diff.png and REF_compare.png being one file).
ShotArgs parse_shot_args(const std::vector<std::string>& args);

/// The images --reference REF.png derives: REF_diff.png and REF_compare.png beside it.
std::filesystem::path reference_diff_path(const std::filesystem::path& reference);
std::filesystem::path reference_compare_path(const std::filesystem::path& reference);

}  // namespace fulgur::app

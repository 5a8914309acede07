// fulgur-bake's command line (kept apart from main so tests can check the validation).
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace fulgur::app {

struct ExportLight {
    std::uint32_t light = 0;
    double weight = 1.0;
};

struct BakeArgs {
    std::filesystem::path scene;
    std::optional<std::filesystem::path> output;  ///< default: bake::default_fgb_path
    bool dry_run = false;
    bool force = false;                           ///< rebake even when the file is up to date
    std::optional<std::filesystem::path> report;  ///< --report FILE.json
    int threads = 0;                              ///< 0: all cores
    std::vector<ExportLight> export_lights;       ///< --export L[:W],...
    int export_direction = 0;                     ///< --direction M
    std::filesystem::path export_prefix;          ///< --nrrd PREFIX -> PREFIX_raw.nrrd, PREFIX_compressed.nrrd
    std::filesystem::path vdb_prefix;             ///< --vdb PREFIX -> PREFIX.vdb (density + S, every direction)
    bool checkpoint = true;                       ///< keep finished lights in OUT.fgb.ckpt/ (--no-checkpoint: not)
    bool fresh = false;                           ///< --fresh: discard OUT.fgb.ckpt/ and bake from scratch
    std::size_t stop_after = 0;                   ///< --stop-after N: SIGKILL itself once N lights are kept (tests)
    bool help = false;
};

std::string bake_usage();

/// Parses argv[1..]. Throws core::Error with a one-line reason on any invalid input.
BakeArgs parse_bake_args(const std::vector<std::string>& args);

}  // namespace fulgur::app

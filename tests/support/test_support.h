// Shared helpers for Fulgur's tests.
#pragma once

#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace fulgur::test {

/// The repository root (for content/, shaders/, tests/ data).
std::filesystem::path source_dir();

/// A fresh, empty directory under the build tree for this test's files.
std::filesystem::path scratch_dir(const std::string& name);

/// core::relative_l2 (||x - ref||_2 / ||ref||_2, the absolute L2 difference when ref is all
/// zero); sizes must match (a failed REQUIRE otherwise).
double relative_l2(std::span<const float> x, std::span<const float> ref);

/// Names of the temporaries and lock files ("*.tmp", "*.lock") in `dir`: a writer that
/// failed or finished leaves none (core::AtomicFile).
std::vector<std::string> temporaries(const std::filesystem::path& dir);

/// `text` with the first occurrence of `from` replaced by `to` (a failed REQUIRE when absent):
/// for scene variants written as edits of one scene text.
std::string replace_once(std::string text, const std::string& from, const std::string& to);

/// The seed of this run's randomized (fuzz-style) loops: FULGUR_TEST_SEED when set (to replay
/// a failure), otherwise a fresh random one; printed once per process so any failure can be
/// replayed.
std::uint64_t run_seed();

/// Writes `text` to `path` (overwriting).
void write_text(const std::filesystem::path& path, const std::string& text);

}  // namespace fulgur::test

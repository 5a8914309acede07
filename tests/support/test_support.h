// Shared helpers for Fulgur's tests.
#pragma once

#include <filesystem>
#include <string>

namespace fulgur::test {

/// The repository root (for content/, shaders/, tests/ data).
std::filesystem::path source_dir();

/// A fresh, empty directory under the build tree for this test's files.
std::filesystem::path scratch_dir(const std::string& name);

/// Writes `text` to `path` (overwriting).
void write_text(const std::filesystem::path& path, const std::string& text);

}  // namespace fulgur::test

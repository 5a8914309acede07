#include "support/test_support.h"

#include "code_version.h"
#include "core/core.h"

#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <random>

namespace fulgur::test {

std::filesystem::path source_dir() { return FULGUR_SOURCE_DIR; }

std::filesystem::path scratch_dir(const std::string& name) {
    const std::filesystem::path p = std::filesystem::path(FULGUR_TEST_OUTPUT_DIR) / name;
    std::filesystem::remove_all(p);
    std::filesystem::create_directories(p);
    return p;
}

std::filesystem::path code_cache_dir(const std::string& name) {
    const std::filesystem::path root = std::filesystem::path(FULGUR_TEST_OUTPUT_DIR) / name;
    const std::string version = std::string(FULGUR_CODE_VERSION).substr(0, 16);
    std::filesystem::create_directories(root);
    for (const auto& e : std::filesystem::directory_iterator(root))
        if (e.path().filename() != version) std::filesystem::remove_all(e.path());
    std::filesystem::create_directories(root / version);
    return root / version;
}

double relative_l2(std::span<const float> x, std::span<const float> ref) {
    REQUIRE(x.size() == ref.size());
    return core::relative_l2(x, ref);
}

std::vector<std::string> temporaries(const std::filesystem::path& dir) {
    std::vector<std::string> out;
    for (const auto& e : std::filesystem::directory_iterator(dir)) {
        const std::string n = e.path().filename().string();
        if (n.ends_with(".tmp") || n.ends_with(".lock")) out.push_back(n);
    }
    return out;
}

std::string replace_once(std::string text, const std::string& from, const std::string& to) {
    const auto at = text.find(from);
    REQUIRE(at != std::string::npos);
    text.replace(at, from.size(), to);
    return text;
}

std::uint64_t run_seed() {
    static const std::uint64_t seed = [] {
        std::uint64_t v = 0;
        if (const char* e = std::getenv("FULGUR_TEST_SEED"))
            v = std::strtoull(e, nullptr, 10);
        else
            v = (std::uint64_t(std::random_device{}()) << 32) ^ std::random_device{}();
        std::printf("randomized loops: seed %llu (replay with FULGUR_TEST_SEED=%llu)\n", (unsigned long long)v,
                    (unsigned long long)v);
        return v;
    }();
    return seed;
}

void write_text(const std::filesystem::path& path, const std::string& text) {
    std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
}

std::string read_text(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

}  // namespace fulgur::test

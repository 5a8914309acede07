// Internal to fulgur::cloud: the parent's side of a contained OpenVDB read (vdb_parent.cpp).
//
// Every read runs in a forked child (vdb_child.h) under a memory limit and a time limit (a
// few seconds plus one per MiB of file). The parent takes nothing on trust: it reads every
// record with bounded sizes, and turns a crash, a kill, a memory or time overrun, a malformed
// record or an error text (cut to a few hundred characters) into core::Error naming the file.
#pragma once

#include "cloud/detail/vdb_child.h"
#include "cloud/detail/vdb_records.h"

#include <sys/types.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace fulgur::cloud::detail::vdb {

// One child per read, its records, and what its end means.
class Reader {
public:
    // Forks the child running body(out) on `path`, whose size is `file_bytes`; it may use
    // `budget` bytes (plus kLibraryBytes), and descriptor_budget() of them until the
    // descriptors are received.
    Reader(const std::filesystem::path& path, std::uint64_t file_bytes, std::uint64_t budget, ChildBody body);
    ~Reader();
    Reader(const Reader&) = delete;
    Reader& operator=(const Reader&) = delete;

    // Errors after the grid is chosen name it.
    void set_where(std::string where) { where_ = std::move(where); }
    // More time for a load whose dense copies take `bytes` (filled as the records arrive): a
    // few-KB file of large active tiles is a valid grid of gigabytes, not a corrupt file.
    void allow_dense(std::uint64_t bytes);
    // The child's share of the memory once the parent knows the dense copies' size (at most
    // the whole budget; the descriptors' share until then).
    void set_budget(std::uint64_t budget) {
        budget_ = std::min(budget, full_budget_);
        rss_limit_ = add_saturated(start_rss_, add_saturated(budget_, kLibraryBytes));
        descriptors_ = false;
    }

    template <class T>
    T get() {
        static_assert(std::is_trivially_copyable_v<T>);
        T v;
        get_bytes(&v, sizeof v);
        return v;
    }
    void get_bytes(void* dst, std::size_t n) {
        auto* p = static_cast<char*>(dst);
        while (n > 0) {
            if (pos_ == end_) refill();
            const std::size_t k = std::min(n, end_ - pos_);
            std::memcpy(p, buf_.data() + pos_, k);
            pos_ += k;
            p += k;
            n -= k;
        }
    }
    // A text of at most `max` bytes.
    std::string get_string(std::size_t max);
    // A tag; an error record is thrown as the refusal it is.
    std::uint8_t get_tag();
    // A record of tag `want` (`what` names it in the refusal of another).
    void expect(std::uint8_t want, const char* what);

    [[noreturn]] void malformed(const std::string& what);

    // After the last record: the child must close the pipe and exit 0.
    void finish();

private:
    struct Ended {};

    void refill();
    void refill_or_end();
    bool reap(int& status);
    [[noreturn]] void end();
    [[noreturn]] void end(int status);

    std::string where_;
    const std::string file_ = where_;
    const std::uint64_t full_budget_;
    std::uint64_t budget_;
    double seconds_;
    std::uint64_t start_rss_ = 0, rss_limit_ = 0;
    pid_t pid_ = -1;
    int fd_ = -1;
    std::chrono::steady_clock::time_point deadline_, next_rss_check_{};
    bool timed_out_ = false, out_of_memory_ = false, eof_ = false;
    bool descriptors_ = true;  // the child may still be reading the descriptors (their budget)
    std::vector<char> buf_ = std::vector<char>(std::size_t(1) << 16);
    std::size_t pos_ = 0, end_ = 0;
};

// The descriptors, bounded: at most kMaxGrids grids, names of at most kMaxNameBytes.
std::vector<GridFacts> receive_facts(Reader& r);

}  // namespace fulgur::cloud::detail::vdb

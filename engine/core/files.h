// fulgur::core — bounded reads and safe writes.
//
// Every file the engine reads is checked first: a regular file (a FIFO would block, /dev/zero
// never ends, a directory is no file) no larger than a limit the format states. Every file it
// writes goes through AtomicFile: never half-written, never through a device, never mixed by
// two writers, and its temporary never left behind by an exception or a signal.
#pragma once

#include "core/grid.h"

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <span>
#include <string>
#include <string_view>

namespace fulgur::core {

/// size. `what` names the kind of file in messages ("scene", "NRRD", ".fgb").
std::uint64_t check_readable_file(const std::filesystem::path& path, std::uint64_t max_bytes, std::string_view what);

/// The whole file after check_readable_file (also fails if the file changes while read).
std::string read_file(const std::filesystem::path& path, std::uint64_t max_bytes, std::string_view what);

/// Throws Error(where, "<what> <i> is NaN|infinite; refusing to write ...") at the first
/// non-finite value: called before any value reaches a file or an image.
void check_finite(std::span<const float> values, std::string_view where, std::string_view what = "value");
/// The same for a grid; the message names the voxel (i,j,k).
void check_finite(const Grid3<float>& grid, std::string_view where);

/// A file a tool reads or writes, with its role in messages ("scene", "output", "report").
struct NamedPath {
    std::string role;
    std::filesystem::path path;
};
/// Throws Error naming the output when an output is one of the inputs or another output (the
/// same path after resolving ".", ".." and symbolic links, or the same file through a hard
/// link), or exists and is not a regular file (a directory, /dev/full): called by the tools
/// before any work, so a bad output costs no bake.
void check_distinct_files(std::span<const NamedPath> inputs, std::span<const NamedPath> outputs);

/// An exclusive advisory lock (flock) on "<target>.lock" for writers of `target` in different
/// processes; waits for the current holder. The lock file is removed on release (and on the
/// signals AtomicFile handles). Nested locks on one target in one process are allowed (the
/// inner one is a no-op): it serializes processes, not the threads of one process.
class FileLock {
public:
    explicit FileLock(const std::filesystem::path& target);
    ~FileLock();
    FileLock(const FileLock&) = delete;
    FileLock& operator=(const FileLock&) = delete;

private:
    std::filesystem::path lock_path_;
};

/// Writes `target` safely: holds its FileLock, writes "<target>.<pid>.tmp" in the same
/// directory, and commit() flushes, syncs, closes (each checked: a full disk or a file-size
/// limit is an Error, not a short file) and renames the temporary over the target atomically.
/// Destroyed without commit() (an exception), or on a terminating signal (SIGINT, SIGTERM,
/// SIGHUP, SIGQUIT, SIGUSR1/2, SIGALRM, SIGVTALRM, SIGPIPE, SIGXCPU), the temporary
/// is removed; temporaries a killed process left for the same target are removed on open. A
/// target that exists but is not a regular file (a directory, a device such as /dev/full) is
/// refused; a symbolic link is followed. Errors name the target.
class AtomicFile {
public:
    explicit AtomicFile(std::filesystem::path target);
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    void write(const void* data, std::size_t n);
    void write(std::string_view bytes) { write(bytes.data(), bytes.size()); }
    /// Moves the write position (for formats whose header is written last).
    void seek(std::uint64_t offset);
    /// The temporary's stream, for writers that need one (stb_image_write, fseek); check
    /// their results and call fail() on error.
    std::FILE* stream();
    [[noreturn]] void fail(const std::string& what);
    void commit();

    const std::filesystem::path& target() const noexcept { return target_; }
    const std::filesystem::path& temp_path() const noexcept { return temp_; }

private:
    void discard() noexcept;
    std::filesystem::path target_, temp_;
    std::unique_ptr<FileLock> lock_;
    std::FILE* file_ = nullptr;
    int slot_ = -1;
    bool committed_ = false;
};

/// `bytes` into `path` through AtomicFile (reports, CSV, SVG).
void write_file(const std::filesystem::path& path, std::string_view bytes);

}  // namespace fulgur::core

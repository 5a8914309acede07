// Bounded reads and safe writes (core.h, "Files"): every file the engine reads is checked to
// be a regular file of bounded size before anything is read or allocated, and every file it
// writes goes through AtomicFile (a temporary in the same directory, checked writes and close,
// an atomic rename, an advisory lock per target, temporaries removed on exceptions and signals).
#include "core/core.h"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <map>
#include <mutex>

namespace fulgur::core {

namespace {

std::string errno_text(int e) { return std::strerror(e); }

// ---------------------------------------------------------------------------------------
// Paths removed when the process is stopped by a signal. Fixed slots, written before they are
// published (state 2), so the handler reads them without locks or allocation.

constexpr int kSlots = 128;
constexpr std::size_t kSlotPath = 4096;
struct Slot {
    std::atomic<int> state{0};  // 0 free, 1 being filled, 2 live
    char path[kSlotPath];
};
Slot g_slots[kSlots];
static_assert(std::atomic<int>::is_always_lock_free, "the signal handler reads the slots lock-free");

// Every signal whose default action ends the process without the program's own handling
// (the crash signals excepted: after a fault, touching the file system is not safe).
constexpr int kCleanupSignals[] = {SIGINT,  SIGTERM, SIGHUP,  SIGQUIT, SIGUSR1,
                                   SIGUSR2, SIGALRM, SIGPIPE, SIGXCPU, SIGVTALRM};
struct sigaction g_previous[NSIG];

extern "C" void remove_temporaries_and_reraise(int sig) {
    for (Slot& s : g_slots)
        if (s.state.load() == 2) ::unlink(s.path);
    const struct sigaction& prev = g_previous[sig];
    if (prev.sa_flags & SA_SIGINFO) {
        prev.sa_sigaction(sig, nullptr, nullptr);  // a handler installed before ours decides what follows
        return;
    }
    if (prev.sa_handler != SIG_DFL && prev.sa_handler != SIG_IGN) {
        prev.sa_handler(sig);
        return;
    }
    ::signal(sig, SIG_DFL);
    ::raise(sig);
}

// Installs the cleanup handler for each signal unless it is already the handler or the signal
// is ignored (e.g. nohup): checked at every registration, so a handler installed after ours is
// kept and chained to rather than silently bypassing the cleanup.
void install_signal_cleanup() {
    static std::mutex mu;
    std::lock_guard lock(mu);
    for (int sig : kCleanupSignals) {
        struct sigaction prev {};
        ::sigaction(sig, nullptr, &prev);
        const bool plain = !(prev.sa_flags & SA_SIGINFO);
        if (plain && (prev.sa_handler == SIG_IGN || prev.sa_handler == remove_temporaries_and_reraise)) continue;
        g_previous[sig] = prev;
        struct sigaction sa {};
        sa.sa_handler = remove_temporaries_and_reraise;
        sigemptyset(&sa.sa_mask);
        ::sigaction(sig, &sa, nullptr);
    }
    // Past a file-size limit (RLIMIT_FSIZE) the default action kills the process and leaves
    // the temporary behind; ignored, the write fails with EFBIG and the error path cleans up.
    ::signal(SIGXFSZ, SIG_IGN);
}

int register_for_signals(const std::string& path) {
    install_signal_cleanup();
    if (path.size() >= kSlotPath) return -1;  // removed on exceptions, not on signals
    for (int i = 0; i < kSlots; ++i) {
        int expected = 0;
        if (g_slots[i].state.compare_exchange_strong(expected, 1)) {
            std::memcpy(g_slots[i].path, path.c_str(), path.size() + 1);
            g_slots[i].state.store(2);
            return i;
        }
    }
    return -1;
}

void unregister_for_signals(int slot) {
    if (slot >= 0) g_slots[slot].state.store(0);
}

// Locks held by this process, by lock-file path: a nested FileLock on the same target is a
// no-op (flock locks belong to an open file description, so a second open would wait on itself).
// Keyed with the process id: a child made by fork() holds none of its parent's locks.
// The last holder to let go releases the lock, whichever object took it.
struct HeldLock {
    int count = 0;
    int fd = -1;
    int slot = -1;
};
std::mutex g_held_mutex;
std::map<std::pair<pid_t, std::string>, HeldLock> g_held;

std::string kind_of(mode_t m) {
    if (S_ISDIR(m)) return "a directory";
    if (S_ISFIFO(m)) return "a FIFO";
    if (S_ISCHR(m)) return "a character device";
    if (S_ISBLK(m)) return "a block device";
    if (S_ISSOCK(m)) return "a socket";
    return "not a regular file";
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Reading

std::uint64_t check_readable_file(const std::filesystem::path& path, std::uint64_t max_bytes, std::string_view what) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0)
        throw Error(path.string(), "cannot open " + std::string(what) + " file: " + errno_text(errno));
    if (!S_ISREG(st.st_mode))
        throw Error(path.string(), "is " + kind_of(st.st_mode) + ", expected a regular " + std::string(what) + " file");
    const auto size = std::uint64_t(st.st_size);
    if (size > max_bytes)
        throw Error(path.string(), std::string(what) + " file is " + format_bytes(double(size)) + " (" +
                                       std::to_string(size) + " bytes); the limit is " + std::to_string(max_bytes) +
                                       " bytes");
    return size;
}

std::string read_file(const std::filesystem::path& path, std::uint64_t max_bytes, std::string_view what) {
    const std::uint64_t size = check_readable_file(path, max_bytes, what);
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd < 0) throw Error(path.string(), "cannot open " + std::string(what) + " file: " + errno_text(errno));
    struct stat st {};
    if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) || std::uint64_t(st.st_size) != size) {
        ::close(fd);  // replaced between the check and the open
        throw Error(path.string(), "changed while it was opened; expected a regular " + std::string(what) + " file");
    }
    std::string text(std::size_t(size), '\0');
    std::size_t got = 0;
    while (got < text.size()) {
        const ssize_t n = ::read(fd, text.data() + got, text.size() - got);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            const int e = errno;
            ::close(fd);
            throw Error(path.string() + " (byte " + std::to_string(got) + ")",
                        n == 0 ? "file shrank while it was read" : "read failed: " + errno_text(e));
        }
        got += std::size_t(n);
    }
    ::close(fd);
    return text;
}

// ---------------------------------------------------------------------------------------
// Finite values

void check_finite(std::span<const float> values, std::string_view where, std::string_view what) {
    for (std::size_t i = 0; i < values.size(); ++i)
        if (!std::isfinite(values[i]))
            throw Error(std::string(where), std::string(what) + " " + std::to_string(i) + " is " +
                                                (std::isnan(values[i]) ? "NaN" : "infinite") +
                                                "; refusing to write a non-finite value");
}

void check_finite(const Grid3<float>& grid, std::string_view where) {
    FULGUR_ASSERT(grid.data.size() == grid.geom.cell_count(), "grid data size does not match its dimensions");
    for (std::size_t i = 0; i < grid.data.size(); ++i)
        if (!std::isfinite(grid.data[i])) {
            const Int3 c = grid.geom.unindex(i);
            throw Error(std::string(where), "voxel (" + std::to_string(c.x) + "," + std::to_string(c.y) + "," +
                                                std::to_string(c.z) + ") is " +
                                                (std::isnan(grid.data[i]) ? "NaN" : "infinite") +
                                                "; refusing to write a non-finite value");
        }
}

// ---------------------------------------------------------------------------------------
// Outputs that are not inputs

void check_distinct_files(std::span<const NamedPath> inputs, std::span<const NamedPath> outputs) {
    auto same = [](const std::filesystem::path& a, const std::filesystem::path& b) {
        // Absolute first: for a relative path none of whose parts exists, weakly_canonical
        // returns it unchanged, so "x" and "./sub/../x" would compare different.
        std::error_code ea, eb;
        const auto ca = std::filesystem::weakly_canonical(std::filesystem::absolute(a, ea), ea),
                   cb = std::filesystem::weakly_canonical(std::filesystem::absolute(b, eb), eb);
        if (!ea && !eb && ca == cb) return true;
        std::error_code ee;
        return std::filesystem::exists(a, ee) && std::filesystem::exists(b, ee) &&
               std::filesystem::equivalent(a, b, ee);  // hard links: one inode, two names
    };
    for (std::size_t o = 0; o < outputs.size(); ++o) {
        // Refused before any work: AtomicFile would refuse it only when the output is written.
        std::error_code ec;
        const auto st = std::filesystem::status(outputs[o].path, ec);
        if (std::filesystem::exists(st) && !std::filesystem::is_regular_file(st))
            throw Error(outputs[o].path.string(),
                        "the " + outputs[o].role + " exists and is " +
                            (std::filesystem::is_directory(st) ? "a directory" : "not a regular file") +
                            "; outputs must be regular files or new");
        for (const NamedPath& in : inputs)
            if (same(outputs[o].path, in.path))
                throw Error(outputs[o].path.string(), "the " + outputs[o].role + " would overwrite the " + in.role +
                                                          " (" + in.path.string() + "); choose another file");
        for (std::size_t p = 0; p < o; ++p)
            if (same(outputs[o].path, outputs[p].path))
                throw Error(outputs[o].path.string(), "the " + outputs[o].role + " and the " + outputs[p].role + " (" +
                                                          outputs[p].path.string() +
                                                          ") are the same file; choose another file");
    }
}

// ---------------------------------------------------------------------------------------
// FileLock

FileLock::FileLock(const std::filesystem::path& target) {
    lock_path_ = target;
    lock_path_ += ".lock";
    std::lock_guard g(g_held_mutex);
    HeldLock& held = g_held[{::getpid(), lock_path_.string()}];
    if (held.count > 0) {
        ++held.count;
        return;
    }
    // Open, lock, and check that the path still names the locked file: a holder unlinks the
    // lock file before it unlocks, so a waiter may have locked a file that is gone (retry).
    int fd = -1;
    for (;;) {
        fd = ::open(lock_path_.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0666);
        if (fd < 0) throw Error(lock_path_.string(), "cannot create the lock file: " + errno_text(errno));
        while (::flock(fd, LOCK_EX) != 0)
            if (errno != EINTR) {
                const int e = errno;
                ::close(fd);
                throw Error(lock_path_.string(), "cannot lock: " + errno_text(e));
            }
        struct stat a {
        }, b{};
        if (::fstat(fd, &a) == 0 && ::stat(lock_path_.c_str(), &b) == 0 && a.st_dev == b.st_dev && a.st_ino == b.st_ino)
            break;
        ::close(fd);
    }
    held = {1, fd, register_for_signals(lock_path_.string())};
}

FileLock::~FileLock() {
    std::lock_guard g(g_held_mutex);
    const auto it = g_held.find({::getpid(), lock_path_.string()});
    if (it == g_held.end() || --it->second.count > 0) return;
    unregister_for_signals(it->second.slot);
    ::unlink(lock_path_.c_str());
    ::close(it->second.fd);
    g_held.erase(it);
}

// ---------------------------------------------------------------------------------------
// AtomicFile

AtomicFile::AtomicFile(std::filesystem::path target) : target_(std::move(target)) {
    std::error_code ec;
    if (std::filesystem::is_symlink(target_, ec)) {
        const auto real = std::filesystem::canonical(target_, ec);
        if (!ec) target_ = real;  // write the file the link points to, not over the link
    }
    const auto st = std::filesystem::status(target_, ec);
    if (std::filesystem::exists(st) && !std::filesystem::is_regular_file(st))
        throw Error(target_.string(), std::string("exists and is ") +
                                          (std::filesystem::is_directory(st) ? "a directory" : "not a regular file") +
                                          "; outputs are written to a temporary and renamed into place, so they must "
                                          "be regular files or new");
    lock_ = std::make_unique<FileLock>(target_);
    // Temporaries of this target left by a process that was killed (SIGKILL cannot be caught):
    // any "<name>.<pid>.tmp" still there while we hold the target's lock is stale.
    const std::filesystem::path dir = target_.has_parent_path() ? target_.parent_path() : ".";
    const std::string prefix = target_.filename().string() + ".";
    for (const auto& e : std::filesystem::directory_iterator(dir, ec)) {
        const std::string n = e.path().filename().string();
        if (n.size() > prefix.size() + 4 && n.starts_with(prefix) && n.ends_with(".tmp") &&
            n.find_first_not_of("0123456789", prefix.size()) == n.size() - 4) {
            std::error_code rm;
            std::filesystem::remove(e.path(), rm);
        }
    }
    temp_ = target_;
    temp_ += "." + std::to_string(::getpid()) + ".tmp";
    const int fd = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd < 0) throw Error(temp_.string(), "cannot open for writing: " + errno_text(errno));
    slot_ = register_for_signals(temp_.string());
    file_ = ::fdopen(fd, "wb");
    if (!file_) {
        const int e = errno;
        ::close(fd);
        discard();
        throw Error(temp_.string(), "cannot open for writing: " + errno_text(e));
    }
}

AtomicFile::~AtomicFile() {
    if (!committed_) discard();
}

void AtomicFile::discard() noexcept {
    if (file_) std::fclose(file_);
    file_ = nullptr;
    ::unlink(temp_.c_str());
    unregister_for_signals(slot_);
    slot_ = -1;
}

void AtomicFile::fail(const std::string& what) {
    const int e = errno;
    discard();
    throw Error(target_.string(), what + ": " + errno_text(e) + " (nothing was written to it)");
}

std::FILE* AtomicFile::stream() {
    FULGUR_ASSERT(file_ && !committed_, "AtomicFile::stream after commit()");
    return file_;
}

void AtomicFile::write(const void* data, std::size_t n) {
    FULGUR_ASSERT(file_ && !committed_, "AtomicFile::write after commit()");
    if (n && std::fwrite(data, 1, n, file_) != n) fail("write failed");
}

void AtomicFile::seek(std::uint64_t offset) {
    FULGUR_ASSERT(file_ && !committed_, "AtomicFile::seek after commit()");
    if (::fseeko(file_, off_t(offset), SEEK_SET) != 0) fail("seek failed");
}

void AtomicFile::commit() {
    FULGUR_ASSERT(file_ && !committed_, "AtomicFile::commit called twice");
    if (std::fflush(file_) != 0) fail("write failed");
    if (::fsync(::fileno(file_)) != 0 && errno != EINVAL) fail("write failed");
    const int rc = std::fclose(file_);
    file_ = nullptr;
    if (rc != 0) fail("write failed");
    if (::rename(temp_.c_str(), target_.c_str()) != 0) fail("cannot move the finished file into place");
    unregister_for_signals(slot_);
    slot_ = -1;
    committed_ = true;
    lock_.reset();
}

void write_file(const std::filesystem::path& path, std::string_view bytes) {
    AtomicFile f(path);
    f.write(bytes.data(), bytes.size());
    f.commit();
}

}  // namespace fulgur::core

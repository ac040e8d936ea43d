// io/isolate.cpp: running a decoder that may crash in a child process (io/io_detail.hpp, run_isolated).
//
// Why: GDCM's JPEG-family decoders abort the process on some broken streams (failed assertions), and OpenVDB can
// corrupt the heap on a file with one byte changed. Validating their input completely would mean re-implementing
// them, so the decode runs in a fork()ed child instead: the child writes warnings, then either an error or the
// result, through a pipe; the parent reads them. A child that dies (a signal, or an exit without a result) becomes
// a FileFormatError naming the file. The child never returns into the caller: it leaves with _exit.
#include <fcntl.h>
#include <signal.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <tbb/task_arena.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>

#include "io/io_detail.hpp"

namespace volrig::io_detail {

namespace {

// Record tags the child writes.
constexpr char kWarning = 'W', kFailure = 'E', kResult = 'K', kReading = 'R';
// Error kinds in a kFailure record.
constexpr char kFormat = 'F', kNotFound = 'N', kOther = 'O';

// Moves n bytes through `step` (::read or ::write on fd), retrying after signals; false when it stops short (the
// other end died or closed the pipe).
template <class Byte, class Step>
bool transfer_all(Byte* p, std::size_t n, Step step) {
    while (n > 0) {
        const ssize_t k = step(p, n);
        if (k < 0 && errno == EINTR) continue;
        if (k <= 0) return false;
        p += k;
        n -= static_cast<std::size_t>(k);
    }
    return true;
}

bool write_all(int fd, const void* data, std::size_t n) {
    return transfer_all(static_cast<const char*>(data), n,
                        [fd](const char* p, std::size_t k) { return ::write(fd, p, k); });
}

// Reads n bytes; false at the end of the pipe (the child died or closed it).
bool read_all(int fd, void* data, std::size_t n) {
    return transfer_all(static_cast<char*>(data), n, [fd](char* p, std::size_t k) { return ::read(fd, p, k); });
}

void send_text(int fd, char tag, const std::string& full) {
    // A message quoting a corrupt file can be huge (OpenVDB quotes a grid type name of any length): cut it.
    const std::string text = full.size() > 4096 ? full.substr(0, 4096) + "..." : full;
    const std::uint64_t n = text.size();
    if (!write_all(fd, &tag, 1) || !write_all(fd, &n, sizeof n) || !write_all(fd, text.data(), text.size())) _exit(3);
}

// The child's data memory now (VmData of /proc/self/status, bytes; 0 when unknown).
std::uint64_t data_memory() {
    std::ifstream status("/proc/self/status");
    std::string key;
    std::uint64_t kb = 0;
    while (status >> key) {
        if (key == "VmData:" && status >> kb) return kb * 1024;
        status.ignore(std::numeric_limits<std::streamsize>::max(), '\n');
    }
    return 0;
}

// Holds the child to `limits` (setrlimit): RLIMIT_DATA at what it maps now plus limits.memory, so a file claiming a
// string or a grid of gigabytes fails at once instead of filling memory for minutes; RLIMIT_CPU at
// limits.cpu_seconds, so a decoder looping over a corrupt tree is stopped (SIGXCPU). A 0 leaves that one unlimited.
void limit_child(const ChildLimits& limits) {
    const std::uint64_t now = data_memory();
    if (limits.memory > 0 && now > 0) {
        const rlimit data{static_cast<rlim_t>(now + limits.memory), static_cast<rlim_t>(now + limits.memory)};
        ::setrlimit(RLIMIT_DATA, &data);
    }
    if (limits.cpu_seconds > 0) {
        const rlimit cpu{static_cast<rlim_t>(limits.cpu_seconds), static_cast<rlim_t>(limits.cpu_seconds + 5)};
        ::setrlimit(RLIMIT_CPU, &cpu);
    }
}

// The child: runs `work`, sends its outcome, and leaves without unwinding into the caller's frames.
[[noreturn]] void child_main(int fd, const std::string& name, const ChildLimits& limits,
                             const std::function<void(IsolatedOutput&)>& work) {
    // A crash must end the child plainly: not in the parent's handlers (Python's faulthandler, Blender's crash
    // report, a test framework's), which would report it as the parent's own.
    for (int sig : {SIGPIPE, SIGABRT, SIGSEGV, SIGBUS, SIGFPE, SIGILL, SIGTRAP, SIGSYS, SIGXCPU}) ::signal(sig, SIG_DFL);
    limit_child(limits);
    try {
        IsolatedOutput out(fd);
        // One thread: the parent's TBB workers do not exist in the child.
        tbb::task_arena arena(1);
        arena.execute([&] { work(out); });
        _exit(0);
    } catch (const FileNotFound& e) {
        send_text(fd, kFailure, std::string(1, kNotFound) + e.what());
    } catch (const FileFormatError& e) {
        send_text(fd, kFailure, std::string(1, kFormat) + e.what());
    } catch (const std::bad_alloc&) {
        send_text(fd, kFailure, limits.memory ? kFormat + name + ": the decoder needed more than the " +
                                                    std::to_string(limits.memory >> 20) + " MiB this file may use "
                                                    "(three times its size budget: max_bytes, or $VOLRIG_MAX_BYTES)"
                                              : kOther + name + ": out of memory");
    } catch (const std::exception& e) {
        send_text(fd, kFailure, std::string(1, kOther) + e.what());
    }
    _exit(0);
}

std::string signal_text(int sig) {
    const char* s = ::strsignal(sig);
    return "signal " + std::to_string(sig) + (s ? std::string(" (") + s + ")" : std::string());
}

// Waits for the child; "" when it exited normally, else what happened to it.
std::string reap(pid_t pid) {
    int status = 0;
    while (::waitpid(pid, &status, 0) < 0)
        if (errno != EINTR) return "lost (" + errno_text(errno) + ")";
    if (WIFSIGNALED(status)) return "killed by " + signal_text(WTERMSIG(status));
    if (WIFEXITED(status) && WEXITSTATUS(status) != 0) return "exited with status " + std::to_string(WEXITSTATUS(status));
    return "";
}

// Rethrows a child's error as the class it had.
[[noreturn]] void rethrow(const std::string& record) {
    const std::string what = record.size() > 1 ? record.substr(1) : std::string("unknown error");
    if (!record.empty() && record[0] == kNotFound) throw FileNotFound(what);
    if (!record.empty() && record[0] == kFormat) throw FileFormatError(what);
    throw Error(what);
}

// The last line the child wrote to its stderr (a failed assertion's text), its last 200 bytes; "" when none.
std::string last_words(int fd) {
    if (fd < 0) return "";
    const off_t end = ::lseek(fd, 0, SEEK_END);
    if (end <= 0) return "";
    const off_t from = end > 400 ? end - 400 : 0;
    std::string text(static_cast<std::size_t>(end - from), '\0');
    const ssize_t r = ::pread(fd, &text[0], text.size(), from);
    text.resize(r > 0 ? static_cast<std::size_t>(r) : 0);
    while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
    const std::size_t nl = text.rfind('\n');
    if (nl != std::string::npos) text.erase(0, nl + 1);
    for (char& c : text)
        if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '?';
    return text.size() > 200 ? "..." + text.substr(text.size() - 200) : text;
}

}  // namespace

IsolatedOutput::IsolatedOutput(int fd) : fd_(fd) {}

void IsolatedOutput::warn(const std::string& text) { send_text(fd_, kWarning, text); }

void IsolatedOutput::reading(const std::string& file) { send_text(fd_, kReading, file); }

void IsolatedOutput::result(const void* data, std::size_t n) {
    const char tag = kResult;
    if (!write_all(fd_, &tag, 1) || !write_all(fd_, data, n)) _exit(3);
}

void IsolatedOutput::more(const void* data, std::size_t n) {
    if (!write_all(fd_, data, n)) _exit(3);
}

bool IsolatedInput::read(void* data, std::size_t n) { return read_all(fd_, data, n); }

ChildLimits decoder_limits(std::uint64_t budget, std::uint64_t work) {
    const std::uint64_t most = std::numeric_limits<std::uint64_t>::max() / 4;
    return {budget >= most ? 0 : 3 * budget + (std::uint64_t(256) << 20),
            work >= most ? 0 : kDecodeSecondsFloor + work / kDecodeBytesPerSecond};
}

ChildLimits decoder_limits(const std::string& path, const ReadOptions& opt) {
    struct stat st {};
    if (::stat(path.c_str(), &st) != 0 || !S_ISREG(st.st_mode)) return decoder_limits(opt.max_bytes, opt.max_bytes);
    const auto file = static_cast<std::uint64_t>(st.st_size);
    const std::uint64_t budget = budget_of(file, opt);
    return decoder_limits(budget, std::min(budget, ratio_allowance(file)));
}

void run_isolated(const std::string& name, const std::string& doing, const ChildLimits& limits,
                  const std::function<void(IsolatedOutput&)>& work,
                  const std::function<void(IsolatedInput&)>& receive,
                  const std::function<void(const std::string&)>& warn) {
    int fds[2];
    if (::pipe2(fds, O_CLOEXEC) != 0) fail(name, "cannot create a pipe for " + doing + ": " + errno_text(errno));
    const int err = ::memfd_create("volrig-decoder-stderr", MFD_CLOEXEC);  // the child's stderr (-1: inherited)
    const pid_t pid = ::fork();
    if (pid < 0) {
        const int e = errno;
        ::close(fds[0]);
        ::close(fds[1]);
        if (err >= 0) ::close(err);
        fail(name, "cannot start a process for " + doing + ": " + errno_text(e));
    }
    if (pid == 0) {
        ::close(fds[0]);
        if (err >= 0) ::dup2(err, 2);
        child_main(fds[1], name, limits, work);
    }
    ::close(fds[1]);
    const int fd = fds[0];
    std::string now;  // the file the child said it decodes (kReading), if it named one
    auto crashed = [&](const std::string& after) {
        ::close(fd);
        const std::string how = reap(pid), said = last_words(err);
        if (err >= 0) ::close(err);
        fail(name, doing + " crashed on " + (now.empty() ? "this file" : now) + " (" + (how.empty() ? after : how) +
                       (said.empty() ? "" : ": " + said) +
                       "): it is corrupt or uses a feature the decoder cannot handle");
    };
    struct CloseErr {
        int fd;
        ~CloseErr() {
            if (fd >= 0) ::close(fd);
        }
    };
    IsolatedInput in(fd);
    for (;;) {
        char tag = 0;
        if (!in.read(&tag, 1)) crashed("it stopped without a result");
        if (tag == kResult) break;
        std::uint64_t n = 0;
        if ((tag != kWarning && tag != kFailure && tag != kReading) || !in.read(&n, sizeof n) ||
            n > (std::uint64_t(1) << 24))
            crashed("it sent a broken record");
        std::string text(static_cast<std::size_t>(n), '\0');
        if (n && !in.read(&text[0], text.size())) crashed("it stopped in a record");
        if (tag == kFailure) {
            ::close(fd);
            reap(pid);
            if (err >= 0) ::close(err);
            rethrow(text);
        }
        if (tag == kReading)
            now = std::move(text);
        else if (warn)
            warn(text);
    }
    const CloseErr close_err{err};
    try {
        receive(in);
    } catch (...) {
        ::close(fd);
        ::kill(pid, SIGKILL);
        reap(pid);
        throw;
    }
    ::close(fd);
    const std::string how = reap(pid);
    if (!how.empty()) fail(name, doing + " crashed after sending its result (" + how + ")");
}

void send_volume(IsolatedOutput& out, const Volume& v) {
    const std::uint64_t n = v.data.size();
    const auto t = static_cast<std::uint8_t>(v.dtype);
    out.result(&v.grid, sizeof(Grid));
    out.more(&t, 1);
    out.more(&n, sizeof n);
    if (n) out.more(v.data.data(), v.data.size());
}

Volume receive_volume(const std::string& name, IsolatedInput& in, std::uint64_t max_bytes) {
    Volume v;
    std::uint8_t t = 0;
    std::uint64_t n = 0;
    if (!in.read(&v.grid, sizeof(Grid)) || !in.read(&t, 1) || !in.read(&n, sizeof n))
        fail(name, "the decoding process stopped while sending its result");
    if (t > static_cast<std::uint8_t>(DType::Float64)) fail(name, "the decoding process sent an unknown voxel type");
    v.dtype = static_cast<DType>(t);
    const std::uint64_t want = static_cast<std::uint64_t>(v.grid.voxel_count()) * dtype_size(v.dtype);
    if (n != want || n > max_bytes) fail(name, "the decoding process sent a volume of an unexpected size");
    v.data.resize(static_cast<std::size_t>(n));
    if (n && !in.read(v.data.data(), v.data.size())) fail(name, "the decoding process stopped while sending voxels");
    return v;
}

Volume isolated_volume(const std::string& name, const std::string& doing, const ReadOptions& opt,
                       const std::function<Volume(const ReadOptions&)>& decode) {
    if (const char* e = std::getenv("VOLRIG_ISOLATE"); e && std::strcmp(e, "0") == 0) return decode(opt);
    Volume v;
    run_isolated(
        name, doing, decoder_limits(name, opt),
        [&](IsolatedOutput& out) {
            ReadOptions child = opt;
            child.warn = [&out](const std::string& w) { out.warn(w); };
            child.reading = [&out](const std::string& f) { out.reading(f); };
            send_volume(out, decode(child));
        },
        [&](IsolatedInput& in) { v = receive_volume(name, in, opt.max_bytes); }, opt.warn);
    return v;
}

}  // namespace volrig::io_detail

// io/write.cpp: writing files: atomic replacement (write_atomically), the FileWriter the format writers use, and
// the checks and byte order of the voxels they write.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <limits>

#include "io/io_detail.hpp"
#include "volrig/io.hpp"

namespace volrig {

namespace {

// The file a write to `path` replaces: `path` itself, or the file its symbolic links lead to (at most 40 links;
// relative links resolve against their own folder), so that a link is written through and keeps pointing there.
std::string write_target(const std::string& path) {
    namespace fs = std::filesystem;
    fs::path p(path);
    std::error_code ec;
    for (int links = 0; links < 40 && fs::is_symlink(fs::symlink_status(p, ec)); ++links) {
        const fs::path to = fs::read_symlink(p, ec);
        if (ec) break;
        p = to.is_absolute() ? to : p.parent_path() / to;
    }
    return p.string();
}

}  // namespace

void write_atomically(const std::string& requested,
                      const std::function<void(const std::string& tmp_path)>& write) {
    static std::atomic<unsigned long> counter{0};
    if (requested.empty()) throw Error("cannot write to an empty path");
    io_detail::check_path(requested);
    const std::string path = write_target(requested);
    struct stat old {};
    const bool replaces = ::stat(path.c_str(), &old) == 0 && S_ISREG(old.st_mode);
    const std::string tmp =
        path + ".tmp-" + std::to_string(static_cast<long>(::getpid())) + "-" + std::to_string(++counter);
    try {
        write(tmp);
        // The replaced file's owner (where this process may give it: root, or a group it is in; else the file
        // becomes the writer's, as a new one would), then its permission bits (after: chown clears set-id bits).
        if (replaces && (old.st_uid != ::geteuid() || old.st_gid != ::getegid()) &&
            ::chown(tmp.c_str(), old.st_uid, old.st_gid) != 0)
            (void)::chown(tmp.c_str(), static_cast<uid_t>(-1), old.st_gid);
        if (replaces && ::chmod(tmp.c_str(), old.st_mode & 07777) != 0)
            throw Error(requested + ": cannot keep the file's permissions: " + io_detail::errno_text(errno));
    } catch (...) {
        std::remove(tmp.c_str());
        throw;
    }
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        const int e = errno;
        std::remove(tmp.c_str());
        throw Error(path + ": cannot move the written file into place: " + io_detail::errno_text(e));
    }
}

namespace io_detail {

FileWriter::FileWriter(const std::string& path, const std::string& shown_as)
    : path_(shown_as.empty() ? path : shown_as) {
    check_path(path);
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (fd_ < 0) {
        const int e = errno;
        if (e == ENOENT || e == ENOTDIR) throw FileNotFound(path_ + ": cannot create the file: " + errno_text(e));
        throw Error(path_ + ": cannot create the file: " + errno_text(e));
    }
}

FileWriter::~FileWriter() {
    if (fd_ >= 0) ::close(fd_);
}

void FileWriter::write(const void* data, std::size_t n) {
    write_at(pos_, data, n);
    pos_ += n;
}

void FileWriter::write_at(std::uint64_t offset, const void* data, std::size_t n) {
    const auto* p = static_cast<const char*>(data);
    while (n > 0) {
        const ssize_t r = ::pwrite(fd_, p, std::min<std::size_t>(n, std::size_t(1) << 30), static_cast<off_t>(offset));
        if (r < 0) {
            if (errno == EINTR) continue;
            throw Error(path_ + ": write failed: " + errno_text(errno));
        }
        p += r;
        n -= static_cast<std::size_t>(r);
        offset += static_cast<std::uint64_t>(r);
    }
}

void FileWriter::close() {
    const int fd = fd_;
    fd_ = -1;
    if (fd >= 0 && ::close(fd) != 0) throw Error(path_ + ": write failed on close: " + errno_text(errno));
}

void check_view(const std::string& path, const VolumeView& v) {
    check_grid(v.grid, dtype_size(v.dtype), std::numeric_limits<std::uint64_t>::max(), path);
    if (!v.data) throw Error(path + ": no voxel data to write");
}

void little_endian_chunks(const VolumeView& v, const std::function<void(const void*, std::size_t)>& sink) {
    const std::size_t esize = dtype_size(v.dtype);
    const std::size_t total = static_cast<std::size_t>(v.grid.voxel_count()) * esize;
    const auto* p = static_cast<const std::uint8_t*>(v.data);
    if (esize == 1 || !host_is_big_endian()) {
        for (std::size_t done = 0; done < total;) {
            const std::size_t step = std::min<std::size_t>(total - done, std::size_t(64) << 20);
            sink(p + done, step);
            done += step;
        }
        return;
    }
    std::vector<std::uint8_t> buf(std::size_t(1) << 20);
    for (std::size_t done = 0; done < total;) {
        const std::size_t step = std::min(total - done, buf.size());
        std::memcpy(buf.data(), p + done, step);
        swap_bytes(buf.data(), step / esize, esize);
        sink(buf.data(), step);
        done += step;
    }
}

}  // namespace io_detail
}  // namespace volrig

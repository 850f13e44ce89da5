#include "core/image/exr_io.h"

#include "core/util/file_io.h"

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <system_error>

namespace tessera::exr_io {

namespace {

std::string errno_text(int err) { return std::error_code(err, std::generic_category()).message(); }

}  // namespace

std::string quoted(const std::filesystem::path& p) { return '"' + p.string() + '"'; }

void MemoryOStream::write(const char c[], int n) {
  const size_t end = pos_ + size_t(n);
  if (end > bytes_.size()) bytes_.resize(end);
  std::memcpy(bytes_.data() + pos_, c, size_t(n));
  pos_ = end;
}

bool MemoryIStream::read(char c[], int n) {
  if (n < 0 || size_t(n) > bytes_.size() - std::min(pos_, bytes_.size()))
    throw std::runtime_error("data ends early (truncated or damaged)");
  std::memcpy(c, bytes_.data() + pos_, size_t(n));
  pos_ += size_t(n);
  return pos_ < bytes_.size();
}

namespace {
constexpr size_t kFileBuffer = size_t(1) << 20;  // AtomicFile writes in pieces of about this size
}  // namespace

AtomicFile::AtomicFile(const std::filesystem::path& path)
    : Imf::OStream(path.c_str()), path_(path), tmp_(temp_path_beside(path)) {
  fd_ = ::open(tmp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
  if (fd_ < 0) throw std::runtime_error("cannot create " + quoted(tmp_) + ": " + errno_text(errno));
  buffer_.reserve(kFileBuffer);
}

AtomicFile::~AtomicFile() {
  if (fd_ >= 0) ::close(fd_);
  if (!committed_) ::unlink(tmp_.c_str());
}

void AtomicFile::fail(const std::string& what, int err) {
  if (failure_.empty()) failure_ = what + ": " + errno_text(err);
  throw std::runtime_error(failure_);
}

void AtomicFile::write_at(const char* data, size_t n, uint64_t at) {
  for (size_t done = 0; done < n;) {
    const ssize_t w = ::pwrite(fd_, data + done, n - done, off_t(at + done));
    if (w < 0 && errno == EINTR) continue;
    if (w <= 0) fail("cannot write " + quoted(tmp_), w < 0 ? errno : EIO);
    done += size_t(w);
  }
}

void AtomicFile::flush() {
  if (buffer_.empty()) return;
  write_at(buffer_.data(), buffer_.size(), buffer_pos_);
  buffer_.clear();
}

void AtomicFile::write(const char c[], int n) {
  if (!failure_.empty()) throw std::runtime_error(failure_);
  if (n <= 0) return;
  if (!buffer_.empty() && (pos_ != buffer_pos_ + buffer_.size() || buffer_.size() + size_t(n) > kFileBuffer)) flush();
  if (size_t(n) >= kFileBuffer) {
    write_at(c, size_t(n), pos_);
  } else {
    if (buffer_.empty()) buffer_pos_ = pos_;
    buffer_.insert(buffer_.end(), c, c + n);
  }
  pos_ += uint64_t(n);
}

void AtomicFile::commit() {
  if (!failure_.empty()) throw std::runtime_error(failure_);
  flush();
  if (const int err = flush_to_disk(fd_)) fail("cannot sync " + quoted(tmp_), err);
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) fail("cannot close " + quoted(tmp_), errno);
  if (::rename(tmp_.c_str(), path_.c_str()) != 0) fail("cannot rename " + quoted(tmp_) + " to " + quoted(path_), errno);
  committed_ = true;
  sync_folder_of(path_);  // the rename made durable; the file is in place, so a failure here is not reported
}

}  // namespace tessera::exr_io

#include "server/file_stream.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <stdexcept>

namespace tessera::server {

namespace {

// Reads the open file from its start, one piece per next(); ends early (the client sees a short body against its
// Content-Length) if a read fails.
class FileStream : public BodyStream {
 public:
  FileStream(int fd, uint64_t size) : fd_(fd), size_(size) {}
  ~FileStream() override { close_file(); }

  void start(std::function<void()> ready) override { ready(); }

  Chunk next() override {
    Chunk c;
    if (fd_ < 0 || offset_ >= size_) {
      c.last = true;
      return c;
    }
    c.text.resize(std::size_t(std::min<uint64_t>(kFilePieceBytes, size_ - offset_)));
    const ssize_t n = ::pread(fd_, c.text.data(), c.text.size(), off_t(offset_));
    if (n <= 0) {
      c.text.clear();
      c.last = true;
      return c;
    }
    c.text.resize(std::size_t(n));
    offset_ += uint64_t(n);
    c.last = offset_ >= size_;
    return c;
  }

  void stop() override { close_file(); }

 private:
  void close_file() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
  }

  int fd_;
  uint64_t size_;
  uint64_t offset_ = 0;
};

}  // namespace

std::optional<HttpReply> file_reply(const std::filesystem::path& path, const char* content_type, unsigned version) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    if (errno == ENOENT) return std::nullopt;
    throw std::runtime_error("cannot open " + path.string() + ": " + std::strerror(errno));
  }
  struct stat st{};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
    ::close(fd);
    throw std::runtime_error(path.string() + " is not a regular file");
  }
  HttpResponse head{http::status::ok, version};
  head.set(http::field::content_type, content_type);
  head.content_length(uint64_t(st.st_size));
  return HttpReply{std::move(head), std::make_shared<FileStream>(fd, uint64_t(st.st_size))};
}

}  // namespace tessera::server

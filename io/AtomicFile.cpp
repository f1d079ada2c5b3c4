#include "io/AtomicFile.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <system_error>

#include "core/Error.hpp"

namespace grainwave::io {

namespace fs = std::filesystem;

fs::path temporary_path(const fs::path& final_path) {
  fs::path tmp = final_path;
  tmp += ".tmp";
  return tmp;
}

void commit_temporary(const fs::path& final_path) {
  std::error_code ec;
  fs::rename(temporary_path(final_path), final_path, ec);
  if (ec)
    throw std::runtime_error("cannot rename " + temporary_path(final_path).string() + " to " +
                             final_path.string() + ": " + ec.message());
}

void write_text_atomically(const fs::path& final_path, const std::string& text) {
  const fs::path tmp = temporary_path(final_path);
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  if (fd < 0) throw std::runtime_error("cannot write " + tmp.string() + ": " + std::strerror(errno));
  std::size_t written = 0;
  while (written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n < 0) {
      const int err = errno;
      ::close(fd);
      throw std::runtime_error("cannot write " + tmp.string() + ": " + std::strerror(err));
    }
    written += static_cast<std::size_t>(n);
  }
  ::fsync(fd);
  ::close(fd);
  commit_temporary(final_path);
}

void ensure_writable_directory(const fs::path& dir, const std::string& what) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec || !fs::is_directory(dir))
    throw InputError({"command line", 0}, what,
                     "cannot create output folder '" + dir.string() + "': " +
                         (ec ? ec.message() : std::string("not a directory")));
  const fs::path probe = dir / ".grainwave-write-probe";
  {
    std::ofstream f(probe);
    if (!f)
      throw InputError({"command line", 0}, what,
                       "output folder '" + dir.string() + "' is not writable");
  }
  fs::remove(probe, ec);
}

}  // namespace grainwave::io

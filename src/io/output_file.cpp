// Output files (output_file.hpp).
#include "htfeti/io/output_file.hpp"

#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <stdexcept>

#include "htfeti/errors.hpp"

namespace htfeti {

namespace fs = std::filesystem;

namespace {

fs::path directory_of(const fs::path& p) {
  return p.parent_path().empty() ? fs::path(".") : p.parent_path();
}

long name_max(const fs::path& dir) {
  errno = 0;
  const long n = ::pathconf(dir.c_str(), _PC_NAME_MAX);
  return n > 0 ? n : 255;
}

}  // namespace

void check_output_path(const std::string& path, const std::string& option) {
  if (path.empty()) throw std::invalid_argument(option + " is empty");
  std::error_code ec;
  const fs::path p(path);
  if (fs::is_directory(p, ec))
    throw std::invalid_argument(option + " '" + path + "' is a directory");
  if (p.filename().empty() || p.filename() == "." || p.filename() == "..")
    throw std::invalid_argument(option + " '" + path + "' names no file");
  const fs::path dir = directory_of(p);
  const long limit = name_max(fs::is_directory(dir, ec) ? dir : fs::path("."));
  if (static_cast<long>(p.filename().string().size()) > limit)
    throw std::invalid_argument(
        option + ": the file name has " + std::to_string(p.filename().string().size()) +
        " characters; the file system takes at most " + std::to_string(limit));
  if (!fs::is_directory(dir, ec))
    throw std::invalid_argument(option + " '" + path + "': directory '" + dir.string() +
                                "' does not exist");
  if (::access(dir.c_str(), W_OK) != 0)
    throw std::invalid_argument(option + " '" + path + "': directory '" + dir.string() +
                                "' is not writable");
  const auto st = fs::status(p, ec);
  if (!ec && fs::exists(st) && !fs::is_regular_file(st) && !fs::is_character_file(st))
    throw std::invalid_argument(option + " '" + path +
                                "' exists and is not a regular file (a FIFO, socket or device "
                                "would block or lose the output)");
}

bool same_file(const std::string& a, const std::string& b) {
  std::error_code ea, eb;
  const fs::path ca = fs::weakly_canonical(fs::absolute(a), ea);
  const fs::path cb = fs::weakly_canonical(fs::absolute(b), eb);
  if (ea || eb) return fs::absolute(a).lexically_normal() == fs::absolute(b).lexically_normal();
  return ca == cb;
}

std::string temporary_name(const std::string& path) {
  const fs::path p(path);
  const std::string name = p.filename().string();
  const std::string suffix = ".htfeti-tmp-" + std::to_string(::getpid());
  std::error_code ec;
  const fs::path dir = directory_of(p);
  std::string tmp = name + suffix;
  if (static_cast<long>(tmp.size()) > name_max(fs::is_directory(dir, ec) ? dir : fs::path(".")))
    tmp = ".htfeti-" + std::to_string(std::hash<std::string>{}(name)) + suffix;
  return (p.parent_path() / tmp).string();
}

void write_atomically(const std::string& path, const std::string& text) {
  std::error_code ec;
  const auto st = fs::status(path, ec);
  if (!ec && fs::exists(st) && !fs::is_regular_file(st)) {  // /dev/null: in place
    std::ofstream o(path);
    o << text << '\n';
    o.flush();
    if (!o) throw IoError("error while writing " + path);
    return;
  }
  const std::string tmp = temporary_name(path);
  {
    std::ofstream o(tmp);
    if (!o) throw IoError("cannot write " + path);
    o << text << '\n';
    o.flush();
    if (!o) {
      o.close();
      fs::remove(tmp, ec);
      throw IoError("error while writing " + path + " (disk full, or a file size limit?)");
    }
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw IoError("cannot rename the output to " + path);
  }
}

}  // namespace htfeti

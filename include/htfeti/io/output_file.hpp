// Output files as a user names them: checked before any work (a usable path, a name the file
// system takes, not a FIFO or a directory, not the same file twice), written under a temporary
// name in the same directory and renamed only when complete, so a failed run leaves nothing.
#pragma once

#include <string>

namespace htfeti {

/// Throws std::invalid_argument naming `option` when `path` cannot be an output file: empty, a
/// directory, in a missing or read-only directory, a name longer than the file system takes,
/// or an existing file that is neither a regular file nor a character device (/dev/null): a
/// FIFO would block the run after the solve.
void check_output_path(const std::string& path, const std::string& option);

/// Whether two paths name the same file (an existing one or not): "x.vtu" and "./x.vtu" do.
bool same_file(const std::string& a, const std::string& b);

/// The temporary name `path` is written under: in the same directory, and short enough for the
/// file system whatever the length of `path`'s own name.
std::string temporary_name(const std::string& path);

/// Writes text to path through temporary_name(path), renamed only when complete; a character
/// device (/dev/null) is written in place, never replaced. Throws IoError (errors.hpp).
void write_atomically(const std::string& path, const std::string& text);

}  // namespace htfeti

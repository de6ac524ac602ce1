// Confinement of a file to a folder, for files named by clients or by model
// files (the web panel's --web folder, a --models folder's buffers).
#pragma once

#include <string>

namespace umbra {

/// True if `path` names a regular file whose real path (every "..", "//"
/// and symlink resolved) lies inside the real path of `folder`; `real` is
/// then that real path. False for an empty folder or a path with a NUL.
bool file_inside_folder(const std::string& folder, const std::string& path, std::string& real);

}  // namespace umbra

#include "assets/folder_file.hpp"

#include <cstdlib>

#include <sys/stat.h>

namespace umbra {

bool file_inside_folder(const std::string& folder, const std::string& path, std::string& real) {
  if (folder.empty() || path.find('\0') != std::string::npos) return false;
  char* root = realpath(folder.c_str(), nullptr);
  char* file = realpath(path.c_str(), nullptr);
  const std::string root_path = root ? root : "", file_path = file ? file : "";
  std::free(root);
  std::free(file);
  if (root_path.empty() || file_path.size() <= root_path.size() + 1 ||
      file_path.compare(0, root_path.size() + 1, root_path + "/") != 0)
    return false;
  struct stat info {};
  if (stat(file_path.c_str(), &info) != 0 || !S_ISREG(info.st_mode)) return false;
  real = file_path;
  return true;
}

}  // namespace umbra

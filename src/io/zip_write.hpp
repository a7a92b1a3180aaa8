#pragma once
// A zip archive of files, stored (not compressed: the viewer's site is mostly a .ply and a
// minified script), for the studio's download of a web site. Entry sizes and the archive below
// 4 GiB (no zip64). Written atomically.
#include <string>
#include <utility>
#include <vector>

namespace ks {

// entries: (name inside the archive, with "/" separators; file on disk).
void write_zip(const std::string& path,
               const std::vector<std::pair<std::string, std::string>>& entries);

// Every regular file under `folder`, named `prefix` + its path relative to the folder.
void write_zip_of_folder(const std::string& path, const std::string& folder,
                         const std::string& prefix);

}  // namespace ks

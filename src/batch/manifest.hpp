#pragma once
// The batch manifest (docs/batch.md): one item a row, an id, a photo and per-item options of the
// item command (`kinesplat create`). Two formats:
//   CSV: a header row naming the columns (`id`, `photo`, then option names such as `steps`);
//        an empty cell leaves that option unset; `#` lines and blank lines are skipped.
//   JSON lines (.jsonl / .ndjson, or any file whose first non-blank character is `{`): one object
//        a line, {"id": "a", "photo": "a.png", "steps": 20, "force": true}.
// Photo paths are relative to the manifest's folder (or absolute). Every problem in a manifest
// (malformed rows, missing photos, duplicate ids, unknown options) is collected and reported in one
// ks::Error before anything runs.
#include <map>
#include <string>
#include <vector>

namespace ks {

// The options the item command accepts: name without the leading "--" -> whether it takes a value
// (false: a flag). The CLI builds this from the `create` subcommand itself.
using ItemOptionSpec = std::map<std::string, bool>;

// Options the batch sets for every item itself; a manifest may not set them.
inline const char* const kBatchOwnedOptions[] = {"out", "help"};

struct ItemOption {
  std::string name;   // without "--"
  std::string value;  // empty for a flag
  bool flag = false;  // true: passed as "--name" alone
};

struct BatchItem {
  std::string id;
  std::string photo;  // absolute
  std::vector<ItemOption> options;
  int line = 0;  // the manifest line the item starts on (1-based)
};

struct Manifest {
  std::string path;
  std::vector<BatchItem> items;
};

// An id must be usable as a folder name and in a shell script unquoted: 1-64 characters of
// [A-Za-z0-9._-], not starting with '.' or '-'.
bool valid_item_id(const std::string& id);

// Parses `path`; throws ks::Error listing every problem (one line each, "PATH:LINE: problem").
Manifest parse_manifest(const std::string& path, const ItemOptionSpec& spec);

// The same from text, for a manifest whose name is `path` (format chosen by its extension, else by
// the first non-blank character); photos are resolved against `base_dir`.
Manifest parse_manifest_text(const std::string& text, const std::string& path,
                             const std::string& base_dir, const ItemOptionSpec& spec);

// The fields of CSV text, one vector a record, with the line each record starts on. Quoted fields
// ("" for a quote) may hold commas and line breaks. Problems (an unterminated quote, text after a
// closing quote) are appended to `errors` as "line N: ...".
struct CsvRecord {
  int line = 0;
  std::vector<std::string> fields;
};
std::vector<CsvRecord> parse_csv(const std::string& text, std::vector<std::string>& errors);

}  // namespace ks

#include "batch/manifest.hpp"

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>

#include "core/error.hpp"
#include "core/fileio.hpp"

namespace fs = std::filesystem;

namespace ks {

namespace {

std::string trim(const std::string& s) {
  size_t b = 0, e = s.size();
  while (b < e && (s[b] == ' ' || s[b] == '\t' || s[b] == '\r')) ++b;
  while (e > b && (s[e - 1] == ' ' || s[e - 1] == '\t' || s[e - 1] == '\r')) --e;
  return s.substr(b, e - b);
}

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return std::tolower(c); });
  return s;
}

bool ends_with(const std::string& s, const std::string& tail) {
  return s.size() >= tail.size() && s.compare(s.size() - tail.size(), tail.size(), tail) == 0;
}

// One row as parsed from either format, before validation: a field's value, or a flag's setting.
struct RawValue {
  std::string text;
  enum Kind { kText, kTrue, kFalse, kNull } kind = kText;
};
struct RawRow {
  int line = 0;
  std::vector<std::pair<std::string, RawValue>> fields;  // in the row's order
};

void csv_rows(const std::string& text, std::vector<RawRow>& rows, std::vector<std::string>& errors,
              int& header_line) {
  std::vector<CsvRecord> records = parse_csv(text, errors);
  if (records.empty()) return;
  const CsvRecord& header = records.front();
  header_line = header.line;
  std::vector<std::string> names;
  std::set<std::string> seen;
  for (const std::string& f : header.fields) {
    std::string n = f;
    if (n.rfind("--", 0) == 0) n = n.substr(2);
    if (n.empty()) errors.push_back("line " + std::to_string(header.line) + ": empty column name");
    if (!seen.insert(n).second)
      errors.push_back("line " + std::to_string(header.line) + ": column '" + n + "' twice");
    names.push_back(n);
  }
  bool header_ok = true;
  for (const char* need : {"id", "photo"})
    if (!seen.count(need)) {
      errors.push_back("line " + std::to_string(header.line) + ": the header row has no '" + need +
                       "' column");
      header_ok = false;
    }
  if (!header_ok) return;
  for (size_t r = 1; r < records.size(); ++r) {
    const CsvRecord& rec = records[r];
    if (rec.fields.size() != names.size()) {
      errors.push_back("line " + std::to_string(rec.line) + ": " +
                       std::to_string(rec.fields.size()) + " fields, the header has " +
                       std::to_string(names.size()));
      continue;
    }
    RawRow row;
    row.line = rec.line;
    for (size_t i = 0; i < names.size(); ++i) {
      RawValue v;
      v.text = rec.fields[i];
      if (v.text.empty()) v.kind = RawValue::kNull;
      row.fields.emplace_back(names[i], v);
    }
    rows.push_back(std::move(row));
  }
}

void jsonl_rows(const std::string& text, std::vector<RawRow>& rows,
                std::vector<std::string>& errors) {
  size_t pos = 0;
  int line = 0;
  while (pos <= text.size()) {
    size_t nl = text.find('\n', pos);
    if (nl == std::string::npos) nl = text.size();
    const std::string s = trim(text.substr(pos, nl - pos));
    ++line;
    pos = nl + 1;
    if (s.empty() || s[0] == '#') continue;
    const std::string at = "line " + std::to_string(line) + ": ";
    nlohmann::json j;
    try {
      j = nlohmann::json::parse(s);
    } catch (const nlohmann::json::parse_error& e) {
      errors.push_back(at + "not valid JSON (" + std::string(e.what()) + ")");
      continue;
    }
    if (!j.is_object()) {
      errors.push_back(at + "expected a JSON object, one item a line");
      continue;
    }
    RawRow row;
    row.line = line;
    bool ok = true;
    for (auto it = j.begin(); it != j.end(); ++it) {
      RawValue v;
      std::string key = it.key();
      if (key.rfind("--", 0) == 0) key = key.substr(2);
      const auto& val = it.value();
      if (val.is_string())
        v.text = val.get<std::string>();
      else if (val.is_number_integer() || val.is_number_unsigned() || val.is_number_float())
        v.text = val.dump();
      else if (val.is_boolean())
        v.kind = val.get<bool>() ? RawValue::kTrue : RawValue::kFalse;
      else if (val.is_null())
        v.kind = RawValue::kNull;
      else {
        errors.push_back(at + "'" + it.key() + "' is " +
                         (val.is_array() ? "an array" : "an object") +
                         " (expected a string, number, boolean or null)");
        ok = false;
        continue;
      }
      row.fields.emplace_back(key, v);
    }
    if (ok) rows.push_back(std::move(row));
  }
}

// A flag's cell: true/false in words or digits.
int parse_flag_setting(const std::string& s) {
  const std::string l = lower(trim(s));
  if (l == "1" || l == "true" || l == "yes" || l == "on") return 1;
  if (l == "0" || l == "false" || l == "no" || l == "off") return 0;
  return -1;
}

}  // namespace

bool valid_item_id(const std::string& id) {
  if (id.empty() || id.size() > 64 || id[0] == '.' || id[0] == '-') return false;
  for (char c : id)
    if (!(std::isalnum(static_cast<unsigned char>(c)) || c == '.' || c == '_' || c == '-'))
      return false;
  return true;
}

std::vector<CsvRecord> parse_csv(const std::string& text, std::vector<std::string>& errors) {
  std::vector<CsvRecord> out;
  size_t i = 0;
  int line = 1;
  const size_t n = text.size();
  while (i < n) {
    // A blank line or a comment line between records.
    size_t eol = text.find('\n', i);
    if (eol == std::string::npos) eol = n;
    const std::string whole = trim(text.substr(i, eol - i));
    if (whole.empty() || whole[0] == '#') {
      i = eol + 1;
      ++line;
      continue;
    }
    CsvRecord rec;
    rec.line = line;
    std::string field;
    bool quoted_field = false, bad = false;
    while (true) {
      if (i < n && text[i] == '"' && trim(field).empty() && !quoted_field) {
        // A quoted field: up to the closing quote ("" is a quote).
        field.clear();
        quoted_field = true;
        const int open_line = line;
        ++i;
        bool closed = false;
        while (i < n) {
          if (text[i] == '"') {
            if (i + 1 < n && text[i + 1] == '"') {
              field += '"';
              i += 2;
              continue;
            }
            ++i;
            closed = true;
            break;
          }
          if (text[i] == '\n') ++line;
          field += text[i++];
        }
        if (!closed) {
          errors.push_back("line " + std::to_string(open_line) + ": unterminated quoted field");
          return out;
        }
        // Only blanks may follow the closing quote before the separator.
        while (i < n && (text[i] == ' ' || text[i] == '\t' || text[i] == '\r')) ++i;
        if (i < n && text[i] != ',' && text[i] != '\n') {
          if (!bad)
            errors.push_back("line " + std::to_string(line) + ": text after a closing quote");
          bad = true;
          while (i < n && text[i] != ',' && text[i] != '\n') ++i;
        }
        continue;
      }
      if (i >= n || text[i] == '\n' || text[i] == ',') {
        rec.fields.push_back(quoted_field ? field : trim(field));
        field.clear();
        quoted_field = false;
        if (i < n && text[i] == ',') {
          ++i;
          continue;
        }
        if (i < n) ++i;  // the newline
        ++line;
        break;
      }
      field += text[i++];
    }
    if (!bad) out.push_back(std::move(rec));
  }
  return out;
}

Manifest parse_manifest_text(const std::string& text, const std::string& path,
                             const std::string& base_dir, const ItemOptionSpec& spec) {
  std::vector<std::string> errors;
  std::vector<RawRow> rows;
  const std::string lp = lower(path);
  bool jsonl = ends_with(lp, ".jsonl") || ends_with(lp, ".ndjson");
  if (!jsonl && !ends_with(lp, ".csv")) {
    const size_t first = text.find_first_not_of(" \t\r\n");
    jsonl = first != std::string::npos && text[first] == '{';
  }
  int header_line = 0;  // CSV: an unknown option is reported once, on the header's line
  if (jsonl)
    jsonl_rows(text, rows, errors);
  else
    csv_rows(text, rows, errors, header_line);
  std::set<std::string> reported;

  Manifest m;
  m.path = path;
  std::map<std::string, int> id_lines;
  for (const RawRow& row : rows) {
    const std::string at = "line " + std::to_string(row.line) + ": ";
    BatchItem item;
    item.line = row.line;
    bool have_id = false, have_photo = false;
    for (const auto& [name, v] : row.fields) {
      if (name == "id" || name == "photo") {
        if (v.kind != RawValue::kText || v.text.empty()) {
          errors.push_back(at + "no " + name);
          continue;
        }
        (name == "id" ? item.id : item.photo) = v.text;
        (name == "id" ? have_id : have_photo) = true;
        continue;
      }
      const std::string where = header_line > 0 ? "line " + std::to_string(header_line) + ": " : at;
      if (std::find_if(std::begin(kBatchOwnedOptions), std::end(kBatchOwnedOptions),
                       [&](const char* o) { return name == o; }) != std::end(kBatchOwnedOptions)) {
        if (header_line == 0 || reported.insert(name).second)
          errors.push_back(where + "option '" + name +
                           "' is set by batch itself (items go to DIR/items/ID)");
        continue;
      }
      const auto it = spec.find(name);
      if (it == spec.end()) {
        if (header_line == 0 || reported.insert(name).second)
          errors.push_back(where + "unknown option '" + name +
                           "' (not an option of the item command)");
        continue;
      }
      if (v.kind == RawValue::kNull) continue;
      ItemOption opt;
      opt.name = name;
      if (!it->second) {  // a flag
        int set = v.kind == RawValue::kTrue    ? 1
                  : v.kind == RawValue::kFalse ? 0
                                               : parse_flag_setting(v.text);
        if (set < 0) {
          errors.push_back(at + "option '" + name + "' is a flag: expected true or false, not '" +
                           v.text + "'");
          continue;
        }
        if (set == 0) continue;
        opt.flag = true;
      } else {
        if (v.kind == RawValue::kTrue || v.kind == RawValue::kFalse)
          opt.value = v.kind == RawValue::kTrue ? "true" : "false";
        else
          opt.value = v.text;
        if (opt.value.find('\n') != std::string::npos) {
          errors.push_back(at + "option '" + name + "' holds a line break");
          continue;
        }
      }
      item.options.push_back(std::move(opt));
    }
    if (!have_id && std::none_of(row.fields.begin(), row.fields.end(),
                                 [](const auto& f) { return f.first == "id"; }))
      errors.push_back(at + "no id");
    if (!have_photo && std::none_of(row.fields.begin(), row.fields.end(),
                                    [](const auto& f) { return f.first == "photo"; }))
      errors.push_back(at + "no photo");
    if (have_id) {
      if (!valid_item_id(item.id))
        errors.push_back(at + "id '" + item.id +
                         "' is not usable as a folder name (1-64 of A-Z a-z 0-9 . _ -, not "
                         "starting with . or -)");
      const auto [pos, fresh] = id_lines.emplace(item.id, row.line);
      if (!fresh)
        errors.push_back(at + "duplicate id '" + item.id + "' (first on line " +
                         std::to_string(pos->second) + ")");
    }
    if (have_photo) {
      fs::path p(item.photo);
      if (p.is_relative()) p = fs::path(base_dir) / p;
      std::error_code ec;
      p = fs::absolute(p, ec).lexically_normal();
      item.photo = p.string();
      if (!fs::exists(p, ec))
        errors.push_back(at + "photo " + item.photo + " does not exist");
      else if (!fs::is_regular_file(p, ec))
        errors.push_back(at + "photo " + item.photo + " is not a file");
    }
    m.items.push_back(std::move(item));
  }
  if (errors.empty() && m.items.empty()) errors.push_back("no items");
  if (!errors.empty()) {
    std::string msg = path + ": " + std::to_string(errors.size()) +
                      (errors.size() == 1 ? " problem" : " problems") + ", nothing was run:";
    for (const std::string& e : errors) msg += "\n  " + path + ": " + e;
    throw Error(msg);
  }
  return m;
}

Manifest parse_manifest(const std::string& path, const ItemOptionSpec& spec) {
  const std::string text = read_file_text(path);
  std::error_code ec;
  const fs::path abs = fs::absolute(path, ec);
  return parse_manifest_text(text, path, abs.parent_path().string(), spec);
}

}  // namespace ks

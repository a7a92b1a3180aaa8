#include "batch/status.hpp"

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

namespace fs = std::filesystem;

namespace ks {

namespace {

bool read_text(const fs::path& p, std::string& out) {
  std::ifstream in(p);
  if (!in) return false;
  std::stringstream ss;
  ss << in.rdbuf();
  out = ss.str();
  return true;
}

std::string first_line(const std::string& s) {
  const size_t nl = s.find('\n');
  return nl == std::string::npos ? s : s.substr(0, nl);
}

}  // namespace

const char* item_state_name(ItemState s) {
  switch (s) {
    case ItemState::kDone:
      return "done";
    case ItemState::kFailed:
      return "failed";
    case ItemState::kRunning:
      return "running";
    case ItemState::kQueued:
      return "queued";
    case ItemState::kPending:
      return "pending";
  }
  return "?";
}

std::string item_dir(const std::string& batch_dir, const std::string& id) {
  return (fs::path(batch_dir) / "items" / id).string();
}

std::string last_error_line(const std::string& log_path) {
  std::ifstream in(log_path);
  std::string line, last;
  while (std::getline(in, line))
    if (line.rfind("error:", 0) == 0) last = line;
  if (last.empty()) return "";
  size_t b = 6;
  while (b < last.size() && last[b] == ' ') ++b;
  while (!last.empty() && (last.back() == '\r' || last.back() == ' ')) last.pop_back();
  return last.substr(b);
}

ItemStatus read_item_status(const std::string& dir) {
  const fs::path d(dir);
  ItemStatus st;
  std::string text;
  if (read_text(d / "submitted", text)) {
    std::istringstream in(text);
    in >> st.submitted_by >> st.job;
    if (st.job == "-") st.job.clear();
  }
  if (read_text(d / "resources", text)) {
    // GNU time writes "Command exited with non-zero status N" / "Command terminated by signal N"
    // before the formatted line: the figures are on the last line.
    std::istringstream in(text);
    std::string line, last;
    while (std::getline(in, line))
      if (!line.empty()) last = line;
    std::istringstream ls(last);
    double s = -1;
    long long kb = -1;
    if (ls >> s >> kb) {
      st.seconds = s;
      st.peak_kb = kb;
    }
  }
  // create.json: the item command's own account.
  std::string create_status, create_error;
  if (read_text(d / "create.json", text)) {
    try {
      const auto j = nlohmann::json::parse(text);
      if (j.is_object()) {
        if (j.contains("status") && j["status"].is_string()) create_status = j["status"];
        if (j.contains("error") && j["error"].is_string()) create_error = j["error"];
      }
    } catch (const nlohmann::json::exception&) {
      create_status = "unreadable";
    }
  }
  std::error_code ec;
  const bool avatar = fs::is_regular_file(d / kItemAvatar, ec);
  const bool done = create_status == "done" && avatar;
  int exit_code = -1;
  const bool ended = read_text(d / "exit_status", text);
  if (ended) {
    std::istringstream in(text);
    if (!(in >> exit_code)) exit_code = -1;
  }
  if (done && (!ended || exit_code == 0)) {
    st.state = ItemState::kDone;
    return st;
  }
  const bool started = fs::exists(d / "started", ec);
  const bool submitted = !st.submitted_by.empty();
  if (!ended) {
    if (started) {
      st.state = ItemState::kRunning;
      return st;
    }
    if (submitted) {
      st.state = ItemState::kQueued;
      return st;
    }
    // Never run through batch: create's own record (a `create` run by hand into this folder).
    if (create_status == "failed") {
      st.state = ItemState::kFailed;
      st.error = first_line(create_error.empty() ? "create failed" : create_error);
      return st;
    }
    st.state = ItemState::kPending;
    return st;
  }
  st.state = ItemState::kFailed;
  std::string why;
  if (create_status == "failed" && !create_error.empty())
    why = create_error;
  else
    why = last_error_line((d / kItemLog).string());
  if (why.empty()) why = last_error_line((d / "task.out").string());  // the task script's own
  if (why.empty()) {
    if (exit_code == 0)
      why = "the item command exited 0 but left no finished avatar (create.json status '" +
            create_status + "')";
    else if (exit_code > 128)
      why = "killed by signal " + std::to_string(exit_code - 128) +
            " (time or memory limit?), see " + (d / kItemLog).string();
    else
      why = "exited with status " + std::to_string(exit_code) + ", see " + (d / kItemLog).string();
  }
  st.error = first_line(why);
  return st;
}

}  // namespace ks

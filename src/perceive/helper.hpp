#pragma once
// The client side of the perceive helper (helpers/perceive/perceive.js): a Node process spoken to
// in JSON lines over its stdin/stdout (one request per line, one response per line, in order; the
// protocol is in docs/perceive.md). Its stderr is collected and quoted in error messages.
#include <sys/types.h>

#include <nlohmann/json.hpp>
#include <string>

namespace ks {

// The helper's folder: $KS_PERCEIVE_HELPER when set (and then only it), else
// <kinesplat executable's folder>/../helpers/perceive, else helpers/perceive in the source tree
// this library was compiled from. Throws ks::Error naming the places looked at and `make deps`
// when none has perceive.js, or when the one found is not installed (no node_modules/ or
// models/.installed).
std::string find_perceive_helper();

struct HelperOptions {
  std::string node = "node";    // the Node.js binary (looked up in PATH)
  double start_timeout_s = 60;  // for the first answer (hello)
  double request_timeout_s = 300;
};

class PerceiveHelper {
 public:
  // Starts `node <dir>/perceive.js` and says hello (checks the protocol version). Throws ks::Error
  // when node is missing, the helper does not start, or it answers nonsense.
  explicit PerceiveHelper(const std::string& dir, const HelperOptions& opts = {});
  ~PerceiveHelper();
  PerceiveHelper(const PerceiveHelper&) = delete;
  PerceiveHelper& operator=(const PerceiveHelper&) = delete;

  // Sends one request (an "id" is added) and returns the response object (which may say
  // "ok": false; the caller decides what that means). Throws ks::Error on a timeout, a crash, or
  // a response that is not one JSON object with the same id; the helper is then stopped.
  nlohmann::json request(nlohmann::json req, double timeout_s);
  nlohmann::json request(const nlohmann::json& req) {
    return request(req, opts_.request_timeout_s);
  }

  const nlohmann::json& hello() const { return hello_; }
  const std::string& dir() const { return dir_; }
  // False once it was stopped (after a timeout, a crash or a malformed answer).
  bool running() const { return pid_ > 0; }
  // What the helper wrote on stderr so far (its last 16 KiB).
  const std::string& stderr_text() const { return err_; }

 private:
  void stop(bool kill_now);
  [[noreturn]] void fail(const std::string& what);

  std::string dir_;
  HelperOptions opts_;
  pid_t pid_ = -1;
  int in_ = -1, out_ = -1, err_fd_ = -1;
  std::string out_buf_, err_;
  long long next_id_ = 1;
  nlohmann::json hello_;
};

}  // namespace ks

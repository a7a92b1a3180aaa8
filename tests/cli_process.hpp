#pragma once
// A kinesplat command (KS_CLI_PATH) as a child process with its output (stdout and stderr) on a
// pipe, for the tests of the long-running commands (`view`, `studio`): start it, read until a
// line appears, stop it with a signal.
#include <poll.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

namespace ks::test {

struct CliProcess {
  pid_t pid = -1;
  int out = -1;
  std::string text;  // everything it printed so far

  bool start(const std::vector<std::string>& args) {
    int fds[2];
    if (::pipe(fds) != 0) return false;
    pid = ::fork();
    if (pid == 0) {
      ::dup2(fds[1], 1);
      ::dup2(fds[1], 2);
      ::close(fds[0]);
      ::close(fds[1]);
      std::vector<std::string> copy = args;
      std::string exe = KS_CLI_PATH;
      std::vector<char*> argv = {exe.data()};
      for (auto& s : copy) argv.push_back(s.data());
      argv.push_back(nullptr);
      ::execv(exe.c_str(), argv.data());
      ::_exit(127);
    }
    ::close(fds[1]);
    out = fds[0];
    return pid > 0;
  }
  // Reads output until it contains `what` or `seconds` pass.
  bool wait_for(const std::string& what, double seconds) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (text.find(what) == std::string::npos) {
      const int ms = int(std::chrono::duration_cast<std::chrono::milliseconds>(
                             end - std::chrono::steady_clock::now())
                             .count());
      if (ms <= 0) return false;
      pollfd p{out, POLLIN, 0};
      if (::poll(&p, 1, ms) <= 0) continue;
      char buf[1024];
      const ssize_t n = ::read(out, buf, sizeof buf);
      if (n <= 0) return text.find(what) != std::string::npos;
      text.append(buf, size_t(n));
    }
    return true;
  }
  // Sends `sig` and returns the exit status (-1: killed after 20 s, or ended by a signal); the
  // last lines it printed are read first.
  int stop(int sig) {
    if (pid <= 0) return -1;
    ::kill(pid, sig);
    int status = 0;
    for (int i = 0; i < 200; ++i) {
      if (::waitpid(pid, &status, WNOHANG) == pid) {
        pid = -1;
        wait_for("\n__never__", 0.5);
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(100));
    }
    ::kill(pid, SIGKILL);
    ::waitpid(pid, &status, 0);
    pid = -1;
    return -1;
  }
  ~CliProcess() {
    if (pid > 0) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, nullptr, 0);
    }
    if (out >= 0) ::close(out);
  }
};

}  // namespace ks::test

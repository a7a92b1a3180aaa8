#pragma once
// A program run by the studio (kinesplat create / export): fork and exec in its own process group
// (so that stopping it stops what it started too: ffmpeg, the perceive helper), standard input
// from /dev/null, standard output and error together on a pipe, read line by line. No file
// descriptor of the server (its sockets) is left open in the child. The child is sent SIGKILL if
// the thread that started it ends (PR_SET_PDEATHSIG), so it never outlives a server that dies.
#include <sys/types.h>

#include <functional>
#include <mutex>
#include <string>
#include <vector>

namespace ks {

class ChildProcess {
 public:
  ChildProcess() = default;
  ~ChildProcess();  // kills the group and reaps the child if still running
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;

  // Starts argv[0] (a path) with these arguments. Throws ks::Error when it cannot.
  void start(const std::vector<std::string>& argv);
  // Reads the output until the child exits, calling `on_line` with each line (without the
  // newline; a carriage return also ends a line). Returns the exit status, 128 + n when killed
  // by signal n.
  int wait(const std::function<void(const std::string&)>& on_line);
  // Asks the whole group to stop (SIGTERM), and kills it (SIGKILL) if it has not exited
  // `grace_ms` later (checked by wait()). Safe from any thread; nothing happens once reaped.
  void terminate(int grace_ms = 3000);
  pid_t pid() const { return pid_; }

 private:
  pid_t pid_ = -1;
  int out_ = -1;
  std::mutex m_;
  bool reaped_ = true;
  long long kill_at_ms_ = -1;  // steady-clock time for SIGKILL; -1: none asked
};

}  // namespace ks

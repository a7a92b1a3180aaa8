#include "studio/child_process.hpp"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>

#include "core/error.hpp"

namespace ks {

namespace {

long long now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

ChildProcess::~ChildProcess() {
  std::unique_lock<std::mutex> lock(m_);
  if (!reaped_ && pid_ > 0) {
    ::kill(-pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
    reaped_ = true;
  }
  if (out_ >= 0) ::close(out_);
}

void ChildProcess::start(const std::vector<std::string>& argv) {
  if (argv.empty()) throw Error("child process: no program given");
  // Everything the child needs is prepared before fork: after it, only async-signal-safe calls.
  std::vector<std::string> copy = argv;
  std::vector<char*> args;
  for (auto& a : copy) args.push_back(a.data());
  args.push_back(nullptr);
  int fds[2];
  if (::pipe2(fds, O_CLOEXEC) != 0)
    throw Error(std::string("child process: pipe: ") + std::strerror(errno));
  const int devnull = ::open("/dev/null", O_RDONLY | O_CLOEXEC);
  rlimit lim{};
  ::getrlimit(RLIMIT_NOFILE, &lim);
  const long max_fd = lim.rlim_cur == RLIM_INFINITY ? 65536 : long(lim.rlim_cur);
  const pid_t parent = ::getpid();
  const pid_t pid = ::fork();
  if (pid < 0) {
    const int e = errno;
    ::close(fds[0]);
    ::close(fds[1]);
    if (devnull >= 0) ::close(devnull);
    throw Error(std::string("child process: fork: ") + std::strerror(e));
  }
  if (pid == 0) {
    ::setpgid(0, 0);
    ::prctl(PR_SET_PDEATHSIG, SIGKILL);
    if (::getppid() != parent) ::_exit(127);  // the parent is already gone
    // Default signal dispositions and no blocked signals (the server may have changed both).
    struct sigaction dfl {};
    dfl.sa_handler = SIG_DFL;
    for (int s : {SIGINT, SIGTERM, SIGPIPE, SIGHUP}) ::sigaction(s, &dfl, nullptr);
    sigset_t none;
    sigemptyset(&none);
    ::sigprocmask(SIG_SETMASK, &none, nullptr);
    if (devnull >= 0) ::dup2(devnull, 0);
    ::dup2(fds[1], 1);
    ::dup2(fds[1], 2);
    // Close every other descriptor: the server's sockets must not live on in the child.
    if (::syscall(SYS_close_range, 3u, ~0u, 0u) != 0)
      for (long fd = 3; fd < max_fd; ++fd) ::close(int(fd));
    ::execv(args[0], args.data());
    const char msg[] = "error: cannot run the program\n";
    (void)!::write(2, msg, sizeof msg - 1);
    ::_exit(127);
  }
  ::setpgid(pid, pid);  // also here, so that the group exists before any terminate()
  ::close(fds[1]);
  if (devnull >= 0) ::close(devnull);
  std::lock_guard<std::mutex> lock(m_);
  pid_ = pid;
  out_ = fds[0];
  reaped_ = false;
  kill_at_ms_ = -1;
}

void ChildProcess::terminate(int grace_ms) {
  std::lock_guard<std::mutex> lock(m_);
  if (reaped_ || pid_ <= 0) return;
  ::kill(-pid_, SIGTERM);
  if (kill_at_ms_ < 0) kill_at_ms_ = now_ms() + grace_ms;
}

int ChildProcess::wait(const std::function<void(const std::string&)>& on_line) {
  std::string pending;
  bool open = out_ >= 0;
  char buf[4096];
  auto emit = [&](bool all) {
    size_t start = 0;
    for (;;) {
      const size_t e = pending.find_first_of("\r\n", start);
      if (e == std::string::npos) break;
      if (e > start && on_line) on_line(pending.substr(start, e - start));
      start = e + 1;
    }
    pending.erase(0, start);
    if (all && !pending.empty()) {
      if (on_line) on_line(pending);
      pending.clear();
    }
  };
  for (;;) {
    {
      std::lock_guard<std::mutex> lock(m_);
      if (kill_at_ms_ >= 0 && now_ms() >= kill_at_ms_ && !reaped_) {
        ::kill(-pid_, SIGKILL);
        kill_at_ms_ = now_ms() + 3600 * 1000;
      }
    }
    if (open) {
      pollfd p{out_, POLLIN, 0};
      const int r = ::poll(&p, 1, 200);
      if (r < 0 && errno != EINTR) open = false;
      if (r > 0) {
        const ssize_t n = ::read(out_, buf, sizeof buf);
        if (n > 0) {
          pending.append(buf, size_t(n));
          emit(false);
        } else if (n == 0 || (errno != EINTR && errno != EAGAIN)) {
          open = false;  // the child (and everything holding the pipe) closed it
        }
      }
      if (open) continue;
      emit(true);
    }
    // The output is closed: wait for the exit, still honouring a SIGKILL deadline.
    int status = 0;
    const pid_t r = ::waitpid(pid_, &status, WNOHANG);
    if (r == pid_) {
      std::lock_guard<std::mutex> lock(m_);
      reaped_ = true;
      ::close(out_);
      out_ = -1;
      if (WIFEXITED(status)) return WEXITSTATUS(status);
      if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
      return 1;
    }
    if (r < 0 && errno != EINTR) {
      std::lock_guard<std::mutex> lock(m_);
      reaped_ = true;
      return 1;
    }
    ::usleep(50 * 1000);
  }
}

}  // namespace ks

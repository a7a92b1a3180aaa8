// The studio's child processes: output lines and exit status, the whole group stopped on
// terminate (grandchildren too), and none of the parent's descriptors left open in the child.
#include "studio/child_process.hpp"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <fstream>
#include <thread>

#include "core/error.hpp"
#include "core/fileio.hpp"
#include "temp_dir.hpp"

namespace ks {
namespace {

// A process that still runs (not gone, and not a zombie waiting for a parent to reap it).
bool running(pid_t pid) {
  std::ifstream stat("/proc/" + std::to_string(pid) + "/stat");
  std::string line;
  if (!std::getline(stat, line)) return false;
  const size_t p = line.rfind(')');
  return p != std::string::npos && p + 2 < line.size() && line[p + 2] != 'Z';
}

std::vector<std::string> run_sh(const std::string& script, int* status) {
  ChildProcess c;
  c.start({"/bin/sh", "-c", script});
  std::vector<std::string> lines;
  *status = c.wait([&](const std::string& l) { lines.push_back(l); });
  return lines;
}

TEST(ChildProcess, LinesAndStatus) {
  int status = -1;
  const auto lines = run_sh("echo one; echo two >&2; printf 'a\\rb\\nlast'; exit 3", &status);
  EXPECT_EQ(status, 3);
  EXPECT_EQ(lines, (std::vector<std::string>{"one", "two", "a", "b", "last"}));
  // Standard input is /dev/null.
  EXPECT_EQ(run_sh("cat; echo done", &status), std::vector<std::string>{"done"});
  EXPECT_EQ(status, 0);
  ChildProcess missing;
  missing.start({"/nonexistent/program"});
  EXPECT_EQ(missing.wait({}), 127);
}

TEST(ChildProcess, KeepsNoDescriptorOfTheParent) {
  test::TempDir dir("child_fds");
  // A descriptor without close-on-exec, as the HTTP library's accepted sockets are.
  const int fd = ::open((dir.path() / "x").c_str(), O_CREAT | O_RDWR, 0600);
  ASSERT_GE(fd, 3);
  int status = -1;
  const auto lines = run_sh("ls /proc/self/fd", &status);
  ::close(fd);
  EXPECT_EQ(status, 0);
  for (const auto& l : lines) EXPECT_LE(std::stoi(l), 3) << "descriptor " << l << " was inherited";
}

TEST(ChildProcess, TerminateStopsTheWholeGroup) {
  test::TempDir dir("child_kill");
  const std::string pids = (dir.path() / "pids").string();
  ChildProcess c;
  // A shell that ignores SIGTERM, with a grandchild: both must go (SIGKILL after the grace).
  c.start({"/bin/sh", "-c", "trap '' TERM; sleep 30 & echo $! > " + pids + "; echo started; wait"});
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    c.terminate(500);
  });
  const auto t0 = std::chrono::steady_clock::now();
  const int status = c.wait({});
  const double took = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  stopper.join();
  EXPECT_EQ(status, 128 + SIGKILL);
  EXPECT_LT(took, 5.0);
  const pid_t grandchild = std::stoi(read_file_text(pids));
  for (int i = 0; i < 50 && running(grandchild); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  EXPECT_FALSE(running(grandchild)) << "the grandchild outlived its group";
  c.terminate();  // after the end: nothing happens
}

}  // namespace
}  // namespace ks

#include "batch/process.h"

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include "core/error.h"

extern char** environ;

namespace rangebayes {
namespace {

struct SpawnActions {
  posix_spawn_file_actions_t actions;
  SpawnActions() { posix_spawn_file_actions_init(&actions); }
  ~SpawnActions() { posix_spawn_file_actions_destroy(&actions); }
  SpawnActions(const SpawnActions&) = delete;
  SpawnActions& operator=(const SpawnActions&) = delete;
};

std::vector<char*> ArgvPointers(const std::vector<std::string>& argv) {
  std::vector<char*> pointers;
  for (const std::string& a : argv) pointers.push_back(const_cast<char*>(a.c_str()));
  pointers.push_back(nullptr);
  return pointers;
}

}  // namespace

std::string SelfExecutable() {
  std::error_code ec;
  const auto path = std::filesystem::read_symlink("/proc/self/exe", ec);
  RB_CHECK(!ec, "/proc/self/exe: cannot find the running executable (", ec.message(), ")");
  return path.string();
}

pid_t StartProcess(const ProcessSpec& spec) {
  RB_CHECK(!spec.argv.empty(), "no program to start");
  SpawnActions a;
  posix_spawn_file_actions_addopen(&a.actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  const std::string out = spec.output_path.empty() ? "/dev/null" : spec.output_path;
  posix_spawn_file_actions_addopen(&a.actions, STDOUT_FILENO, out.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_adddup2(&a.actions, STDOUT_FILENO, STDERR_FILENO);
  if (!spec.working_dir.empty()) posix_spawn_file_actions_addchdir_np(&a.actions, spec.working_dir.c_str());
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  if (spec.own_process_group) {
    posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
    posix_spawnattr_setpgroup(&attributes, 0);
  }
  std::vector<char*> argv = ArgvPointers(spec.argv);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, argv[0], &a.actions, &attributes, argv.data(), environ);
  posix_spawnattr_destroy(&attributes);
  RB_CHECK(rc == 0, spec.argv[0], ": cannot start (", std::strerror(rc), ")");
  return pid;
}

ProcessExit DecodeWaitStatus(int status) {
  ProcessExit e;
  if (WIFEXITED(status)) {
    e.exit_code = WEXITSTATUS(status);
  } else if (WIFSIGNALED(status)) {
    e.signal = WTERMSIG(status);
    e.exit_code = 128 + e.signal;
  }
  return e;
}

ProcessExit WaitProcess(pid_t pid) {
  int status = 0;
  while (waitpid(pid, &status, 0) < 0) {
    RB_CHECK(errno == EINTR, "waitpid ", pid, ": ", std::strerror(errno));
  }
  return DecodeWaitStatus(status);
}

void WaitUntilEnded(pid_t pid) {
  siginfo_t info{};
  while (waitid(P_PID, static_cast<id_t>(pid), &info, WEXITED | WNOWAIT) != 0) {
    RB_CHECK(errno == EINTR, "waitid ", pid, ": ", std::strerror(errno));
  }
}

CapturedRun RunAndCapture(const std::vector<std::string>& argv) {
  CapturedRun run;
  RB_CHECK(!argv.empty(), "no program to run");
  int out_pipe[2], err_pipe[2];
  RB_CHECK(pipe2(out_pipe, O_CLOEXEC) == 0 && pipe2(err_pipe, O_CLOEXEC) == 0, "pipe: ", std::strerror(errno));
  SpawnActions a;
  posix_spawn_file_actions_addopen(&a.actions, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&a.actions, out_pipe[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&a.actions, err_pipe[1], STDERR_FILENO);
  std::vector<char*> pointers = ArgvPointers(argv);
  pid_t pid = 0;
  const int rc = posix_spawnp(&pid, pointers[0], &a.actions, nullptr, pointers.data(), environ);
  close(out_pipe[1]);
  close(err_pipe[1]);
  if (rc != 0) {
    close(out_pipe[0]);
    close(err_pipe[0]);
    run.error = std::strerror(rc);
    return run;
  }
  run.started = true;
  std::array<pollfd, 2> fds{{{out_pipe[0], POLLIN, 0}, {err_pipe[0], POLLIN, 0}}};
  std::array<std::string*, 2> sinks{&run.out, &run.err};
  int open_fds = 2;
  std::array<char, 4096> buffer{};
  while (open_fds > 0) {
    if (poll(fds.data(), fds.size(), -1) < 0) {
      if (errno == EINTR) continue;
      break;
    }
    for (size_t i = 0; i < fds.size(); ++i) {
      if (fds[i].fd < 0 || fds[i].revents == 0) continue;
      const ssize_t n = read(fds[i].fd, buffer.data(), buffer.size());
      if (n > 0) {
        sinks[i]->append(buffer.data(), static_cast<size_t>(n));
      } else if (n == 0 || errno != EINTR) {
        close(fds[i].fd);
        fds[i].fd = -1;
        --open_fds;
      }
    }
  }
  run.exit = WaitProcess(pid);
  return run;
}

std::string LastLine(const std::string& text) {
  size_t end = text.find_last_not_of(" \t\r\n");
  if (end == std::string::npos) return "";
  const size_t start = text.find_last_of('\n', end);
  return text.substr(start == std::string::npos ? 0 : start + 1, end - (start == std::string::npos ? 0 : start + 1) + 1);
}

}  // namespace rangebayes

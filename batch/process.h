// Child processes for batch: the rangebayes binary itself (tasks, local workers) and Slurm's commands.
#pragma once

#include <sys/types.h>

#include <string>
#include <vector>

namespace rangebayes {

// Absolute path of the running executable (/proc/self/exe). Throws when it cannot be read.
std::string SelfExecutable();

struct ProcessSpec {
  std::vector<std::string> argv;  // argv[0] is the program: a path, or a name looked up on PATH
  std::string working_dir;        // empty: the caller's
  std::string output_path;        // stdout and stderr appended here (created); empty: /dev/null
  // The process leads a process group of its own, so that a signal to the group (kill(-pid, ...)) reaches
  // whatever it starts, and nothing else.
  bool own_process_group = false;
};

// Starts a process with stdin from /dev/null. Throws rangebayes::Error naming the program when it cannot be
// started (not found, not executable).
pid_t StartProcess(const ProcessSpec& spec);

// How a process ended: exit code 0-255, or 128 + signal with `signal` set.
struct ProcessExit {
  int exit_code = -1;
  int signal = 0;
};
ProcessExit DecodeWaitStatus(int status);

// Waits for `pid`, retrying on EINTR.
ProcessExit WaitProcess(pid_t pid);

// Waits until `pid` has ended, retrying on EINTR, without reaping it: until WaitProcess, its pid (and the process
// group it leads) cannot be taken by another process, so a late signal to it reaches no one else.
void WaitUntilEnded(pid_t pid);

// A finished command and what it printed.
struct CapturedRun {
  bool started = false;  // false: the program was not found or not executable (`error` says why)
  std::string error;
  ProcessExit exit;
  std::string out, err;
};

// Runs argv (argv[0] looked up on PATH) to completion and captures stdout and stderr separately.
CapturedRun RunAndCapture(const std::vector<std::string>& argv);

// The last line of `text` that is not blank ("" if none).
std::string LastLine(const std::string& text);

}  // namespace rangebayes

// fork+exec of helper binaries with bounded waits, for the cross-process tests and for
// ppf_latency_bench (it starts the node it measures): a caller must fail, never hang, and never
// leave a child behind.
#pragma once

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace ppf::dds {

class ChildProcess {
 public:
  ChildProcess() = default;
  ChildProcess(const ChildProcess&) = delete;
  ChildProcess& operator=(const ChildProcess&) = delete;
  ~ChildProcess() { Kill(); }

  // Starts argv[0] (a path) with extra "KEY=VALUE" environment entries. stdout is captured
  // (ReadLine); stderr is inherited so the child's log ends up in the test log, or redirected to
  // `stderr_file` when given.
  bool Start(const std::vector<std::string>& argv, const std::vector<std::string>& env = {},
             const std::string& stderr_file = "") {
    int fds[2];
    if (pipe(fds) != 0) return false;
    stderr_file_ = stderr_file;
    pid_ = fork();
    if (pid_ < 0) return false;
    if (pid_ == 0) {
      dup2(fds[1], STDOUT_FILENO);
      close(fds[0]);
      close(fds[1]);
      if (!stderr_file.empty()) {
        const int fd = open(stderr_file.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0) {
          dup2(fd, STDERR_FILENO);
          close(fd);
        }
      }
      // Die with the test process even if it is killed hard.
      setpgid(0, 0);
      for (const auto& e : env) putenv(strdup(e.c_str()));
      std::vector<char*> args;
      for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
      args.push_back(nullptr);
      execv(args[0], args.data());
      _exit(127);
    }
    close(fds[1]);
    out_fd_ = fds[0];
    fcntl(out_fd_, F_SETFL, fcntl(out_fd_, F_GETFL) | O_NONBLOCK);
    return true;
  }

  pid_t pid() const { return pid_; }
  // Where the child's stderr goes ("" = inherited).
  const std::string& stderr_file() const { return stderr_file_; }
  // Whether stdout reached EOF (the child closed it: it exited, or is exiting).
  bool stdout_closed() const { return out_fd_ < 0; }

  // Next line of the child's stdout, or false if none arrives within `timeout` / on EOF.
  bool ReadLine(std::string* line, std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (true) {
      const size_t nl = buffer_.find('\n');
      if (nl != std::string::npos) {
        *line = buffer_.substr(0, nl);
        buffer_.erase(0, nl + 1);
        return true;
      }
      if (out_fd_ < 0) return false;
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) return false;
      pollfd p{out_fd_, POLLIN, 0};
      if (poll(&p, 1, static_cast<int>(left.count())) <= 0) continue;
      char buf[4096];
      const ssize_t n = read(out_fd_, buf, sizeof(buf));
      if (n > 0) {
        buffer_.append(buf, static_cast<size_t>(n));
      } else if (n == 0) {
        close(out_fd_);
        out_fd_ = -1;
      }
    }
  }

  // Reads lines until one starts with `prefix`; all lines read are appended to `seen`.
  bool WaitForLine(const std::string& prefix, std::string* line, std::chrono::milliseconds timeout,
                   std::vector<std::string>* seen = nullptr) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    std::string l;
    while (true) {
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(
          deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0 || !ReadLine(&l, left)) return false;
      if (seen) seen->push_back(l);
      if (l.rfind(prefix, 0) == 0) {
        *line = l;
        return true;
      }
    }
  }

  void Signal(int sig) {
    if (pid_ > 0) kill(pid_, sig);
  }

  // Exit status (as from waitpid) or -1 if the child did not exit in time.
  int Wait(std::chrono::milliseconds timeout) {
    if (pid_ <= 0) return status_;
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (true) {
      int status = 0;
      const pid_t r = waitpid(pid_, &status, WNOHANG);
      if (r == pid_) {
        pid_ = -1;
        status_ = status;
        return status;
      }
      if (std::chrono::steady_clock::now() >= deadline) return -1;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }

  void Kill() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
      pid_ = -1;
    }
    if (out_fd_ >= 0) {
      close(out_fd_);
      out_fd_ = -1;
    }
  }

 private:
  pid_t pid_ = -1;
  int out_fd_ = -1;
  int status_ = -1;
  std::string buffer_;
  std::string stderr_file_;
};

inline bool ExitedWith(int status, int code) {
  return status >= 0 && WIFEXITED(status) && WEXITSTATUS(status) == code;
}

}  // namespace ppf::dds

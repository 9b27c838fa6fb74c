// Positioned and direct writes of a file's byte ranges, for the binary VTU writer (vtu.cpp):
// write_all, and the two pieces of its direct-I/O path, WriteBehind (one background thread that
// writes filled stages) and DirectStream (one thread's values of one array, staged in aligned
// blocks). Private to src/io.
#pragma once

#include <fcntl.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <memory>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

namespace htfeti::vtu_io {

// Writes n bytes at `at` with positioned writes (a write may take less than asked); false on an
// error (disk full, I/O error).
inline bool write_all(int fd, const char* data, size_t n, std::uint64_t at) {
  while (n > 0) {
    const ssize_t w = ::pwrite(fd, data, n, static_cast<off_t>(at));
    if (w <= 0) return false;
    data += w, n -= static_cast<size_t>(w), at += static_cast<std::uint64_t>(w);
  }
  return true;
}

// Background writes of whole staged blocks by direct I/O: one thread that takes the filled
// stages of every stream in the order they were handed over and writes them with positioned
// writes, so that the threads that fill the stages (meshes, values) do not wait for the disk
// while it has work. A stage is handed over with a flag that the writer clears when the stage
// is on the disk (or failed); its owner waits for that flag before it fills the stage again.
class WriteBehind {
 public:
  WriteBehind(int fd, int dfd) : fd_(fd), dfd_(dfd), thread_([this] { run(); }) {}
  ~WriteBehind() {
    {
      std::lock_guard<std::mutex> l(m_);
      stop_ = true;
    }
    cv_.notify_all();
    thread_.join();
  }
  WriteBehind(const WriteBehind&) = delete;
  WriteBehind& operator=(const WriteBehind&) = delete;

  void submit(const char* data, size_t n, std::uint64_t at, bool* in_flight) {
    {
      std::lock_guard<std::mutex> l(m_);
      *in_flight = true;
      jobs_.push_back({data, n, at, in_flight});
    }
    cv_.notify_all();
  }
  void wait(const bool* in_flight) {
    std::unique_lock<std::mutex> l(m_);
    cv_.wait(l, [&] { return !*in_flight; });
  }
  std::string error() {
    std::lock_guard<std::mutex> l(m_);
    return error_;
  }

 private:
  struct Job {
    const char* data;
    size_t n;
    std::uint64_t at;
    bool* in_flight;
  };
  void run() {
    std::unique_lock<std::mutex> l(m_);
    for (;;) {
      cv_.wait(l, [&] { return stop_ || !jobs_.empty(); });
      if (jobs_.empty()) return;  // stop_ and nothing left
      const Job j = jobs_.front();
      jobs_.pop_front();
      const bool skip = !error_.empty();  // after an error the rest is not written
      l.unlock();
      const bool ok = skip || write(j);
      l.lock();
      if (!ok && error_.empty()) error_ = "error while writing the VTU (disk full?)";
      *j.in_flight = false;
      cv_.notify_all();
    }
  }
  bool write(const Job& j) const {
    size_t done = 0;
    while (done < j.n) {
      const ssize_t w = ::pwrite(dfd_, j.data + done, j.n - done, static_cast<off_t>(j.at + done));
      if (w < 0 && errno == EINVAL)  // direct I/O refused here: the page cache
        return write_all(fd_, j.data + done, j.n - done, j.at + done);
      if (w <= 0) return false;
      done += static_cast<size_t>(w);
    }
    return true;
  }
  int fd_, dfd_;
  std::mutex m_;
  std::condition_variable cv_;
  std::deque<Job> jobs_;
  std::string error_;
  bool stop_ = false;
  std::thread thread_;  // last: started after the members it uses
};

// One thread's values of one array: the contiguous byte range [begin, end) of the file, appended
// in order. The 4 KiB blocks wholly inside the range go to the file by direct I/O from two
// aligned staging buffers of a MiB: one is filled while the other is written (WriteBehind). The
// bytes before the range's first block boundary and after its last lie in blocks shared with
// the neighbouring ranges and are written through the page cache (`fd`), as is everything when
// the direct write is refused (EINVAL).
class DirectStream {
 public:
  static constexpr std::uint64_t kBlock = 4096, kStage = std::uint64_t{1} << 20;
  DirectStream(int fd, WriteBehind& writer, std::uint64_t begin, std::uint64_t end)
      : fd_(fd), writer_(&writer), pos_(begin), end_(end) {
    lo_ = (begin + kBlock - 1) / kBlock * kBlock;
    hi_ = end / kBlock * kBlock;
    if (hi_ <= lo_) lo_ = hi_ = end;  // no whole block: all through the page cache
    stage_at_ = lo_;
  }
  DirectStream(DirectStream&& o) noexcept
      : fd_(o.fd_),
        writer_(o.writer_),
        pos_(o.pos_),
        end_(o.end_),
        lo_(o.lo_),
        hi_(o.hi_),
        stage_at_(o.stage_at_),
        fill_(o.fill_),
        cur_(o.cur_) {
    for (int s = 0; s < 2; ++s) {  // moved before any write (vector growth): nothing in flight
      stage_[s] = std::move(o.stage_[s]);
      in_flight_[s] = false;
    }
    o.writer_ = nullptr;
  }
  DirectStream(const DirectStream&) = delete;
  DirectStream& operator=(const DirectStream&) = delete;
  DirectStream& operator=(DirectStream&&) = delete;
  ~DirectStream() {  // the stages must stay until the writer is done with them
    if (writer_)
      for (int s = 0; s < 2; ++s) writer_->wait(&in_flight_[s]);
  }

  void append(const char* data, size_t n) {
    if (pos_ + n > end_) throw std::logic_error("VTU: a piece's values overrun their range");
    while (n > 0) {
      if (pos_ < lo_ || pos_ >= hi_) {  // a partial block at either end
        const size_t k =
            static_cast<size_t>(std::min<std::uint64_t>(n, (pos_ < lo_ ? lo_ : end_) - pos_));
        buffered(data, k, pos_);
        data += k, n -= k, pos_ += k;
        continue;
      }
      if (!stage_[cur_]) {
        stage_[cur_].reset(static_cast<char*>(std::aligned_alloc(kBlock, kStage)));
        if (!stage_[cur_]) throw std::bad_alloc();
      }
      const size_t k =
          static_cast<size_t>(std::min<std::uint64_t>({n, kStage - fill_, hi_ - pos_}));
      std::memcpy(stage_[cur_].get() + fill_, data, k);
      fill_ += k, data += k, n -= k, pos_ += k;
      if (fill_ == kStage || pos_ == hi_) hand_over();
    }
  }
  /// Waits until this stream's values are on the disk; throws on a write error.
  void finish() {
    if (pos_ != end_) throw std::logic_error("VTU: a piece's values fall short of their range");
    for (int s = 0; s < 2; ++s) writer_->wait(&in_flight_[s]);
    const std::string e = writer_->error();
    if (!e.empty()) throw std::runtime_error(e);
  }

 private:
  void buffered(const char* data, size_t n, std::uint64_t at) {
    if (!write_all(fd_, data, n, at))
      throw std::runtime_error("error while writing the VTU (disk full?)");
  }
  void hand_over() {  // fill_ is a whole number of blocks here
    writer_->submit(stage_[cur_].get(), fill_, stage_at_, &in_flight_[cur_]);
    stage_at_ += fill_;
    fill_ = 0;
    cur_ ^= 1;
    writer_->wait(&in_flight_[cur_]);  // the other stage: free once its write is done
  }
  int fd_;
  WriteBehind* writer_;
  std::uint64_t pos_, end_, lo_ = 0, hi_ = 0, stage_at_ = 0;
  size_t fill_ = 0;
  int cur_ = 0;  // the stage being filled
  struct Free {
    void operator()(char* p) const { std::free(p); }
  };
  std::unique_ptr<char[], Free> stage_[2];  // aligned_alloc'd, kStage bytes, made on first use
  bool in_flight_[2] = {false, false};      // guarded by the writer's mutex
};

}  // namespace htfeti::vtu_io

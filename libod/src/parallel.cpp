#include "cairn/od/parallel.hpp"

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <deque>
#include <exception>
#include <mutex>
#include <system_error>
#include <vector>

namespace cairn::od::internal {
namespace {

// A team's call for helpers: open while its caller works, closed (taken off the queue) when
// it has every helper it asked for or the caller is done.
struct Team {
  const std::function<void(int)>* work;
  int wanted;                   // helpers still wanted
  int joined = 0;               // helpers that took a worker number
  std::atomic<int> running{0};  // helpers inside work(); changed under the pool's mutex
  std::exception_ptr error = nullptr;  // the first helper's exception (under the pool's mutex)
};

// About how long a thread that waits for the pool spins before it sleeps. A sleeping thread
// takes tens to hundreds of microseconds to wake (more on a virtual machine), as long as a
// whole stage of the detector on one frame; its stages follow each other within
// microseconds, but a serial step between two (a tree's tasks, the segments' ids) can take
// longer than 50 us. The spin yields, so a thread with work still gets the core. (50 and 200 us
// were as fast on an Intel Xeon; on an AMD EPYC, 500 us against 50 took the detector on both
// cores from 9.4 and 10.6 ms to 9.1 and 8.4 on KITTI, 5.4 and 5.7 to 4.9 and 5.1 on the demo
// frame (two sets of six rounds), and left `cairn map` as it was: BENCHMARKS.md.)
constexpr std::chrono::microseconds kSpin{500};

// Spins until `ready()` or kSpin has passed; returns ready().
template <class Ready>
bool SpinUntil(const Ready& ready) {
  const auto until = std::chrono::steady_clock::now() + kSpin;
  for (int i = 1;; ++i) {
    if (ready()) return true;
    if (i % 8 == 0 && std::chrono::steady_clock::now() > until) return false;
    std::this_thread::yield();
  }
}

class Pool {
 public:
  int Run(int helpers, const std::function<void(int)>& work) {
    if (helpers < 1) {
      work(0);
      return 1;
    }
    Team team{&work, helpers};
    {
      std::lock_guard<std::mutex> lock(mutex_);
      // Helpers for this loop besides those busy with others' or promised to them (the loops
      // of two threads, as `cairn map`'s detection beside its fusion, each get theirs, as
      // with threads of their own).
      Grow(busy_ + pending_ + helpers);
      if (!threads_.empty()) {
        teams_.push_back(&team);
        pending_ += helpers;
        open_.store(static_cast<int>(teams_.size()));
      }
    }
    if (helpers == 1) {
      wake_.notify_one();
    } else {
      wake_.notify_all();
    }
    try {
      work(0);
    } catch (...) {
      Finish(&team);  // the team lives on this stack: no helper may hold it any more
      throw;
    }
    Finish(&team);
    if (team.error) std::rethrow_exception(team.error);
    return 1 + team.joined;
  }

 private:
  // Starts threads until there are `n` (as far as the system lets: a thread it cannot start,
  // EAGAIN on a loaded machine, leaves the work to those there are). Under mutex_.
  void Grow(int n) {
    while (static_cast<int>(threads_.size()) < n) {
      try {
        threads_.emplace_back([this] { Serve(); });
      } catch (const std::system_error&) {
        return;
      }
    }
  }

  // Takes the team off the queue and waits for the helpers that joined it.
  void Finish(Team* team) {
    std::unique_lock<std::mutex> lock(mutex_);
    for (auto it = teams_.begin(); it != teams_.end(); ++it) {
      if (*it == team) {
        teams_.erase(it);
        pending_ -= team->wanted;
        open_.store(static_cast<int>(teams_.size()));
        break;
      }
    }
    // No helper joins from here on. Seeing `running` at 0 orders after every joined helper's
    // work (its decrement releases it), and a helper touches the team no more after that.
    if (team->running.load() == 0) return;
    lock.unlock();
    if (SpinUntil([&] { return team->running.load() == 0; })) return;
    lock.lock();
    done_.wait(lock, [&] { return team->running.load() == 0; });
  }

  void Serve() {
    std::unique_lock<std::mutex> lock(mutex_);
    for (;;) {
      if (teams_.empty()) {
        lock.unlock();
        SpinUntil([&] { return open_.load() != 0; });
        lock.lock();
      }
      wake_.wait(lock, [&] { return !teams_.empty(); });
      Team* team = teams_.front();
      const int worker = ++team->joined;
      ++team->running;
      ++busy_;
      --pending_;
      if (--team->wanted == 0) {
        teams_.pop_front();
        open_.store(static_cast<int>(teams_.size()));
      }
      lock.unlock();
      std::exception_ptr error;
      try {
        (*team->work)(worker);
      } catch (...) {
        error = std::current_exception();
      }
      lock.lock();
      if (error && !team->error) team->error = error;
      --busy_;
      if (--team->running == 0) done_.notify_all();
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_, done_;
  std::deque<Team*> teams_;
  std::vector<std::thread> threads_;
  int busy_ = 0;     // threads inside some team's work()
  int pending_ = 0;  // helpers still wanted by the teams in the queue
  // A mirror of teams_.size() (written under mutex_), read while spinning.
  std::atomic<int> open_{0};
};

}  // namespace

int RunTeam(int helpers, const std::function<void(int)>& work) {
  // Never destroyed: a loop may still run when static objects are destroyed at exit (a
  // thread of the caller's, a static destructor), and the idle threads end with the process.
  // (A child made by fork() while loops run has no pool threads: its loops run on the calling
  // thread alone.)
  static Pool& pool = *new Pool;
  return pool.Run(helpers, work);
}

}  // namespace cairn::od::internal

#include <future>
#include <memory>
#include <optional>
#include <utility>

#include "cairn/sources/frame_source.hpp"

namespace cairn::sources {
namespace {

// The next frame of `inner` read by a task of its own (std::async) while the caller works on
// the current one. Only that task touches `inner` while it runs; everything else waits for
// it first, so `inner` is used by one thread at a time, in the order of the calls.
class ReadAheadSource final : public FrameSource {
 public:
  explicit ReadAheadSource(std::unique_ptr<FrameSource> inner) : inner_(std::move(inner)) {}
  ~ReadAheadSource() override { Settle(); }

  Expected<std::optional<SequenceFrame>> Next() override {
    Expected<std::optional<SequenceFrame>> next =
        pending_.valid() ? pending_.get() : inner_->Next();
    // After an error or the end the caller stops: nothing more is read.
    if (next && *next) {
      pending_ = std::async(std::launch::async, [source = inner_.get()] { return source->Next(); });
    }
    return next;
  }

  Status Skip(int n) override {
    if (n > 0 && pending_.valid()) {  // the frame read ahead is the first of those skipped
      Expected<std::optional<SequenceFrame>> ahead = pending_.get();
      if (!ahead) return ahead.error();
      if (!*ahead || --n == 0) return Status::Ok();  // at the end, or that was all
    }
    return inner_->Skip(n);
  }

  int total() const override {
    Settle();
    return inner_->total();
  }
  SourceInfo Describe() const override {
    Settle();
    return inner_->Describe();
  }
  const Trajectory& trajectory() const override {
    Settle();
    return inner_->trajectory();
  }

 private:
  void Settle() const {
    if (pending_.valid()) pending_.wait();
  }

  std::unique_ptr<FrameSource> inner_;
  mutable std::future<Expected<std::optional<SequenceFrame>>> pending_;
};

}  // namespace

std::unique_ptr<FrameSource> ReadAhead(std::unique_ptr<FrameSource> source) {
  return std::make_unique<ReadAheadSource>(std::move(source));
}

}  // namespace cairn::sources

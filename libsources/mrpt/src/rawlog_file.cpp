#include "cairn/sources/rawlog_file.hpp"

#include <mrpt/img/CImage.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/serialization/CArchive.h>
#include <unistd.h>

#include <exception>
#include <system_error>

#include "cairn/sources/mrpt_convert.hpp"
#include "mrpt_errors.hpp"

namespace cairn::sources {
namespace {

namespace fs = std::filesystem;
using ::mrpt::obs::CObservation;
using detail::Describe;

}  // namespace

std::string EntryName(const fs::path& path, int entry) {
  return path.string() + ": entry " + std::to_string(entry);
}

// ---------------------------------------------------------------------------------------
// Writer

Expected<RawlogWriter> RawlogWriter::Create(const fs::path& path, int gzip_level) {
  if (gzip_level < 0 || gzip_level > 9) {
    return Error{path.string() + ": gzip level " + std::to_string(gzip_level) + " (expected 0..9)"};
  }
  RawlogWriter writer;
  writer.path_ = path;
  writer.temp_path_ = path;
  writer.temp_path_ += ".tmp-" + std::to_string(::getpid());
  writer.out_ = std::make_unique<::mrpt::io::CFileGZOutputStream>();
  bool opened = false;
  try {
    opened = writer.out_->open(writer.temp_path_.string(), gzip_level);
  } catch (const std::exception&) {
    opened = false;
  }
  if (!opened) {
    writer.out_.reset();
    return Error{path.string() + ": cannot open for writing (is its directory there?)"};
  }
  return writer;
}

RawlogWriter::~RawlogWriter() {
  if (out_) {
    out_.reset();  // closes
    std::error_code ec;
    fs::remove(temp_path_, ec);
  }
}

Status RawlogWriter::Write(const ::mrpt::serialization::CSerializable& object) {
  if (!out_) return Error{path_.string() + ": already committed"};
  try {
    auto archive = ::mrpt::serialization::archiveFrom(*out_);
    archive << object;
  } catch (const std::exception& e) {
    return Error{path_.string() + ": cannot write object " + std::to_string(written_) + " (a " +
                 ShortClassName(object.GetRuntimeClass()->className) + "): " + Describe(e)};
  }
  ++written_;
  return {};
}

Status RawlogWriter::Commit() {
  if (!out_) return Error{path_.string() + ": already committed"};
  try {
    out_->close();
  } catch (const std::exception& e) {
    return Error{path_.string() + ": cannot close: " + Describe(e)};
  }
  out_.reset();
  std::error_code ec;
  fs::rename(temp_path_, path_, ec);
  if (ec) {
    fs::remove(temp_path_, ec);
    return Error{path_.string() + ": cannot rename the temporary file into place: " + ec.message()};
  }
  return {};
}

// ---------------------------------------------------------------------------------------
// Reader

// The gzip stream with one byte of look-ahead: MRPT reports both a clean end of file and a
// file cut inside an object as CExceptionEOF, so the reader asks before each object whether
// any byte is left.
class RawlogReader::Stream : public ::mrpt::io::CStream {
 public:
  explicit Stream(::mrpt::io::CFileGZInputStream& file) : file_(file) {}

  bool AtEnd() {
    if (has_peek_) return false;
    has_peek_ = file_.Read(&peek_, 1) == 1;
    return !has_peek_;
  }

  size_t Read(void* buffer, size_t count) override {
    if (count == 0) return 0;
    auto* out = static_cast<std::uint8_t*>(buffer);
    size_t n = 0;
    if (has_peek_) {
      out[0] = peek_;
      has_peek_ = false;
      n = 1;
    }
    // A gzip stream may return fewer bytes than asked before its end: keep reading.
    while (n < count) {
      const size_t got = file_.Read(out + n, count - n);
      if (got == 0) break;
      n += got;
    }
    return n;
  }
  size_t Write(const void*, size_t) override { return 0; }
  uint64_t Seek(int64_t, ::mrpt::io::CStream::TSeekOrigin) override {
    throw std::runtime_error("rawlog stream: seeking is not supported");
  }
  uint64_t getTotalBytesCount() const override { return file_.getTotalBytesCount(); }
  uint64_t getPosition() const override { return file_.getPosition() - (has_peek_ ? 1 : 0); }

 private:
  ::mrpt::io::CFileGZInputStream& file_;
  std::uint8_t peek_ = 0;
  bool has_peek_ = false;
};

Expected<RawlogReader> RawlogReader::Open(const fs::path& path) {
  std::error_code ec;
  if (!fs::exists(path, ec)) return Error{path.string() + ": no such file"};
  if (!fs::is_regular_file(path, ec)) return Error{path.string() + ": not a regular file"};
  RawlogReader reader;
  reader.path_ = path;
  reader.file_ = std::make_unique<::mrpt::io::CFileGZInputStream>();
  std::string message;
  bool opened = false;
  try {
    opened = reader.file_->open(path.string(), message);
  } catch (const std::exception& e) {
    message = Describe(e);
  }
  if (!opened) {
    return Error{path.string() + ": cannot open for reading" +
                 (message.empty() ? std::string() : ": " + message)};
  }
  reader.stream_ = std::make_unique<Stream>(*reader.file_);
  // MRPT's convention: "<dir>/<stem>_Images", else "<dir>/Images". (Computed here: MRPT's
  // CRawlog::detectImagesDirectory misreads directories whose names hold a '.'.)
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  fs::path images = dir / (path.stem().string() + "_Images");
  if (!fs::is_directory(images, ec)) images = dir / "Images";
  if (!fs::is_directory(images, ec)) images = dir;
  ::mrpt::img::CImage::setImagesPathBase(images.string());
  return reader;
}

RawlogReader::RawlogReader(RawlogReader&&) noexcept = default;
RawlogReader& RawlogReader::operator=(RawlogReader&&) noexcept = default;
RawlogReader::~RawlogReader() = default;

Expected<std::optional<RawlogEntry>> RawlogReader::NextEntry() {
  if (stream_->AtEnd()) return std::optional<RawlogEntry>();
  RawlogEntry entry;
  entry.index = entries_;
  try {
    auto archive = ::mrpt::serialization::archiveFrom(*stream_);
    entry.object = archive.ReadObject();
  } catch (const std::bad_alloc&) {
    return Error{EntryName(path_, entries_) +
                 ": corrupt rawlog: an object claims more memory than there is"};
  } catch (const std::exception& e) {
    return Error{EntryName(path_, entries_) + ": truncated or corrupt rawlog (or not a rawlog): " +
                 Describe(e)};
  }
  if (!entry.object) return Error{EntryName(path_, entries_) + ": a null object"};
  ++entries_;
  return std::optional<RawlogEntry>(std::move(entry));
}

Expected<CObservation::Ptr> RawlogReader::Next() {
  while (pending_.empty()) {
    Expected<std::optional<RawlogEntry>> entry = NextEntry();
    if (!entry) return entry.error();
    if (!*entry) return CObservation::Ptr();
    const auto& object = (*entry)->object;
    if (auto obs = std::dynamic_pointer_cast<CObservation>(object)) {
      pending_.push_back(std::move(obs));
    } else if (auto frame = std::dynamic_pointer_cast<::mrpt::obs::CSensoryFrame>(object)) {
      for (const CObservation::Ptr& o : *frame) {
        if (o) pending_.push_back(o);
      }
    } else if (!std::dynamic_pointer_cast<::mrpt::obs::CActionCollection>(object)) {
      return Error{EntryName(path_, (*entry)->index) + ": a " +
                   ShortClassName(object->GetRuntimeClass()->className) +
                   ", not an observation, sensory frame or action collection"};
    }
  }
  CObservation::Ptr next = std::move(pending_.front());
  pending_.pop_front();
  return next;
}

Expected<std::vector<CObservation::Ptr>> ReadRawlogObservations(const fs::path& path) {
  Expected<RawlogReader> reader = RawlogReader::Open(path);
  if (!reader) return reader.error();
  std::vector<CObservation::Ptr> observations;
  while (true) {
    Expected<CObservation::Ptr> next = reader->Next();
    if (!next) return next.error();
    if (!*next) break;
    observations.push_back(std::move(*next));
  }
  return observations;
}

}  // namespace cairn::sources

// MRPT rawlog files: reading them object by object, and writing them crash-safely.
//
// A rawlog is a sequence of serialised MRPT objects (plain or gzip-compressed). Two layouts
// exist: the observations format (a flat list of CObservation objects) and the
// actions/sensory-frames format (CSensoryFrame, CActionCollection, CSensoryFrame, ...: the
// actions are the robot's motion between the frames). Both are read here.
//
// Externally stored images (CImage and range images kept beside the rawlog in
// "<stem>_Images/", else "Images/") are found through MRPT's process-wide images path, which
// RawlogReader::Open sets to the opened file's images directory (the last opened wins).
#pragma once

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/obs/CObservation.h>
#include <mrpt/serialization/CSerializable.h>

#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cairn/od/expected.hpp"

namespace cairn::sources {

/// Writes a rawlog into a temporary file beside `path`, renamed over `path` by Commit(): a
/// reader never sees a half-written rawlog. Abandoned (destroyed without Commit), the
/// temporary is removed. gzip level 0 writes a plain file, 1..9 a gzip-compressed one (MRPT
/// reads both). Move-only.
class RawlogWriter {
 public:
  static Expected<RawlogWriter> Create(const std::filesystem::path& path, int gzip_level = 1);
  RawlogWriter(RawlogWriter&&) noexcept = default;
  RawlogWriter& operator=(RawlogWriter&&) noexcept = default;
  ~RawlogWriter();

  /// Appends one object (an observation, a sensory frame, an action collection). Fails,
  /// naming the file, when writing fails.
  Status Write(const ::mrpt::serialization::CSerializable& object);
  /// Closes and renames into place. Nothing can be written afterwards.
  Status Commit();

  int objects_written() const { return written_; }
  const std::filesystem::path& path() const { return path_; }

 private:
  RawlogWriter() = default;
  std::filesystem::path path_, temp_path_;
  std::unique_ptr<::mrpt::io::CFileGZOutputStream> out_;
  int written_ = 0;
};

/// One top-level object of a rawlog.
struct RawlogEntry {
  int index = 0;  ///< 0-based position in the file
  ::mrpt::serialization::CSerializable::Ptr object;
};

/// Reads a rawlog (plain or gzip) object by object. Move-only.
class RawlogReader {
 public:
  /// Fails, naming the file, when it is missing or cannot be opened. A zero-byte file opens
  /// (as an empty rawlog, as MRPT reads it).
  static Expected<RawlogReader> Open(const std::filesystem::path& path);
  RawlogReader(RawlogReader&&) noexcept;
  RawlogReader& operator=(RawlogReader&&) noexcept;
  ~RawlogReader();

  /// The next top-level object, or nullopt at the end of the file. Fails on a truncated or
  /// corrupt file or an unknown class, naming the file and the entry. Any class is accepted.
  Expected<std::optional<RawlogEntry>> NextEntry();

  /// The next observation, or nullptr at the end of the file: observations-format files give
  /// their observations, sensory-frame files the observations of each CSensoryFrame in turn;
  /// actions are skipped. Fails like NextEntry, and on an object that is neither an
  /// observation, a sensory frame nor an action collection.
  Expected<::mrpt::obs::CObservation::Ptr> Next();

  /// Entries (top-level objects) read so far.
  int entries_read() const { return entries_; }
  const std::filesystem::path& path() const { return path_; }

 private:
  class Stream;  // the file with one byte of look-ahead, to tell its end from truncation
  RawlogReader() = default;
  std::filesystem::path path_;
  std::unique_ptr<::mrpt::io::CFileGZInputStream> file_;
  std::unique_ptr<Stream> stream_;
  std::deque<::mrpt::obs::CObservation::Ptr> pending_;
  int entries_ = 0;
};

/// Every observation of a rawlog, in file order (see RawlogReader::Next).
Expected<std::vector<::mrpt::obs::CObservation::Ptr>> ReadRawlogObservations(
    const std::filesystem::path& path);

/// "<file>: entry <n>" — how errors about one object of a file begin.
std::string EntryName(const std::filesystem::path& path, int entry);

}  // namespace cairn::sources

#include "core/image/exr_stream.h"

#include "core/image/exr_layout.h"
#include "core/image/exr_zip.h"
#include "core/util/file_io.h"

#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>

#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>

namespace tessera {

struct ExrStream::Impl {
  ExrWriteOptions layout;                    // the file's layout (no metadata)
  exr_io::MemoryOStream draft{"(draft)"};  // the file under a header without metadata
  std::optional<Imf::Header> header;         // the draft's header, from the first band
  std::unique_ptr<Imf::OutputFile> out;      // writing the draft, until finish() or a failure
  std::optional<ZipChunkStream> zip;         // instead of the draft: a ZIP file's chunks, made by libdeflate
  int rows = 0;                              // rows of the data window written
  bool stopped = false;                      // a band failed, or finish() has spent the stream

  // When the draft holds every row in the layout of (img, opt), writes the file to `file` from its blocks and
  // returns true; otherwise returns false. Spends the stream either way. Throws std::runtime_error when (img, opt)
  // is refused as encode_exr refuses it, and whatever OpenEXR or `file` throws.
  bool reuse(Imf::OStream& file, const Image& img, const ExrWriteOptions& opt);
};

ExrStream::ExrStream(const ExrWriteOptions& layout) : impl_(std::make_unique<Impl>()) {
  if (layout.data_window.empty()) throw ImageError("an EXR stream needs a non-empty data window");
  impl_->layout = layout;
  impl_->layout.metadata.clear();
}

ExrStream::~ExrStream() = default;

int ExrStream::rows_written() const { return impl_->rows; }

bool ExrStream::complete() const {
  return !impl_->stopped && (impl_->out || impl_->zip) && impl_->rows == impl_->layout.data_window.height();
}

void ExrStream::write_rows(const Image& band) {
  Impl& s = *impl_;
  if (s.stopped) throw ImageError("cannot write EXR rows: the stream has stopped");
  try {
    const PixelWindow& data = s.layout.data_window;
    exr_layout::data_window(band, s.layout, /*band=*/true);  // the band's shape and width
    if (band.height > data.height() - s.rows)
      throw std::runtime_error(std::to_string(band.height) + " rows after row " + std::to_string(s.rows) +
                               " go past the data window's " + std::to_string(data.height()));
    Imf::Header h = exr_layout::header(band, s.layout, data);
    const PixelWindow rows{data.x0, data.y0 + s.rows, data.x1, data.y0 + s.rows + band.height};
    const exr_layout::Frame frame = exr_layout::frame(band, s.layout, rows);
    const std::optional<exr_scanline::Lines> lines = exr_scanline::Lines::of(h, frame.buffer);
    if (!s.header) {
      s.header = std::move(h);
      if (zip_lines_per_chunk(s.header->compression()) > 0 && lines) {
        s.header->sanityCheck();  // refused here, as OutputFile would refuse it
        s.zip.emplace(*s.header);
      } else {
        // No threads of its own: OpenEXR compresses the band's blocks on the calling thread.
        s.out = std::make_unique<Imf::OutputFile>(s.draft, *s.header, 0);
      }
    } else if (!(h.channels() == s.header->channels())) {
      throw std::runtime_error("the band's channels differ from the first band's");
    }
    if (s.zip) {
      if (!lines) throw std::runtime_error("the band's layout differs from the first band's");
      s.zip->add(*lines, rows.y0, rows.y1);  // compressed on the calling thread
    } else {
      s.out->setFrameBuffer(frame.buffer);
      s.out->writePixels(band.height);  // OpenEXR reads only these rows from the frame buffer
    }
    s.rows += band.height;
  } catch (const std::exception& e) {
    s.stopped = true;
    s.out.reset();
    s.zip.reset();
    throw ImageError(std::string("cannot write EXR rows: ") + e.what());
  }
}

bool ExrStream::Impl::reuse(Imf::OStream& file, const Image& img, const ExrWriteOptions& opt) {
  const bool whole = !stopped && (out || zip) && rows == layout.data_window.height();
  stopped = true;
  if (!whole) {
    out.reset();
    zip.reset();
    return false;
  }
  const PixelWindow data = exr_layout::data_window(img, opt);
  const Imf::Header final_header = exr_layout::header(img, opt, data);
  exr_layout::check_extra_sizes(img, opt);  // refused as encode_exr would, though the values are not read
  if (data != layout.data_window || final_header.compression() != header->compression() ||
      !(final_header.channels() == header->channels())) {
    out.reset();
    zip.reset();
    return false;
  }
  if (zip) {
    const bool fits = zip->fits(final_header);  // the channels are the same, checked above
    if (fits) zip->write(file, final_header);  // the compressed chunks as they are
    zip.reset();
    return fits;
  }
  out.reset();  // completes the draft (its line offset table)
  const std::vector<uint8_t>& bytes = draft.bytes();
  exr_io::MemoryIStream in_stream(std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()),
                                      "(draft)");
  Imf::InputFile in(in_stream, 0);
  Imf::OutputFile final_file(file, final_header, 0);
  final_file.copyPixels(in);  // the compressed blocks as they are
  return true;
}  // final_file's destructor completes the file (its line offset table)

std::vector<uint8_t> ExrStream::finish(const Image& img, const ExrWriteOptions& opt) {
  try {
    try {
      exr_io::MemoryOStream file("memory");
      file.reserve(impl_->draft.bytes().size() + 65536);  // the draft's blocks and a header with metadata, most likely
      if (impl_->reuse(file, img, opt)) return file.take();
    } catch (const std::exception&) {
      // A refused image is refused again below; any trouble with the draft leaves the image itself to encode.
    }
    return exr_layout::encode("memory", img, opt);
  } catch (const std::exception& e) {
    throw ImageError(std::string("cannot encode EXR: ") + e.what());
  }
}

void ExrStream::write(const std::filesystem::path& path, const Image& img, const ExrWriteOptions& opt) {
  try {
    {
      // Written straight to the temporary file: the blocks are not copied once more in memory.
      exr_io::AtomicFile file(path);
      bool reused = false;
      try {
        reused = impl_->reuse(file, img, opt);
      } catch (const std::exception&) {
        if (file.failed()) throw;  // the file, not the draft: encoding afresh would fail the same way
      }
      if (reused) {
        file.commit();
        return;
      }
    }  // the temporary file goes
    write_file_atomic(path, exr_layout::encode(path.c_str(), img, opt));
  } catch (const std::exception& e) {
    throw ImageError("cannot write EXR " + exr_io::quoted(path) + ": " + e.what());
  }
}

}  // namespace tessera

#include "capture/libcamera_source.h"

#include <libcamera/libcamera.h>
#include <sys/mman.h>

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdlib>
#include <deque>
#include <map>
#include <mutex>

#include "capture/device_list.h"
#include "core/error.h"

namespace rangebayes {

void LibcameraStereoOptions::Check() const {
  RB_CHECK(width >= 1 && height >= 1, "camera size must be positive, got ", width, "x", height);
  RB_CHECK(buffers >= 2 && buffers <= 16, "libcamera buffers must be 2..16, got ", buffers);
  RB_CHECK(timeout_ms >= 1 && timeout_ms <= 60000, "camera timeout must be 1..60000 ms, got ", timeout_ms);
  pairing.Check();
}

namespace {
// libcamera logs INFO/WARN lines (missing IPA modules on a PC) to stderr; keep a user's own setting.
void QuietLibcameraLogs() { setenv("LIBCAMERA_LOG_LEVELS", "*:ERROR", 0); }
}  // namespace

LibcameraList ListLibcameraCameras() {
  QuietLibcameraLogs();
  LibcameraList list;
  auto manager = std::make_unique<libcamera::CameraManager>();
  const int r = manager->start();
  if (r != 0) {
    list.error = StrCat("libcamera CameraManager did not start (error ", r, ")");
    return list;
  }
  list.manager_started = true;
  for (const std::shared_ptr<libcamera::Camera>& camera : manager->cameras()) {
    LibcameraCameraInfo info;
    info.id = camera->id();
    const auto model = camera->properties().get(libcamera::properties::Model);
    if (model) info.model = *model;
    list.cameras.push_back(info);
  }
  manager->stop();
  return list;
}

namespace {

// One camera's stream: configuration, buffers mapped for reading, and completed images waiting for pairing.
struct CameraStream {
  std::shared_ptr<libcamera::Camera> camera;
  std::unique_ptr<libcamera::CameraConfiguration> config;
  std::unique_ptr<libcamera::FrameBufferAllocator> allocator;
  std::vector<std::unique_ptr<libcamera::Request>> requests;
  struct Mapping {
    void* base = nullptr;
    size_t length = 0;
    size_t offset = 0;
  };
  std::map<const libcamera::FrameBuffer*, Mapping> mapped;
  libcamera::Stream* stream = nullptr;
  int width = 0, height = 0, stride = 0;
  std::string format;
  bool acquired = false;
  // Read on libcamera's callback thread (to requeue a completed request), written by Start and ~Impl.
  std::atomic<bool> started{false};
  SequenceGapCounter gaps;
};

}  // namespace

struct LibcameraStereoSource::Impl {
  LibcameraStereoOptions options;
  std::unique_ptr<libcamera::CameraManager> manager;
  CameraStream cams[2];
  std::mutex mutex;
  std::condition_variable ready;
  FramePairer pairer;
  FrameSourceStats stats;
  std::int64_t next_index = 0;
  std::string failure;  // set from the callback thread when a camera reports an error

  explicit Impl(const LibcameraStereoOptions& o) : options(o), pairer(o.pairing) {}

  void OnRequestComplete(int side, libcamera::Request* request) {
    if (request->status() == libcamera::Request::RequestCancelled) return;
    CameraStream& cs = cams[side];
    const auto& buffers = request->buffers();
    if (buffers.empty()) return;
    const libcamera::FrameBuffer* buffer = buffers.begin()->second;
    const libcamera::FrameMetadata& md = buffer->metadata();
    TimedImage image;
    image.timestamp_ns = static_cast<std::int64_t>(md.timestamp);
    image.sequence = md.sequence;
    const auto it = cs.mapped.find(buffer);
    if (md.status == libcamera::FrameMetadata::FrameSuccess && it != cs.mapped.end()) {
      const cv::Mat y(cs.height, cs.width, CV_8UC1, static_cast<char*>(it->second.base) + it->second.offset,
                    static_cast<size_t>(cs.stride));
      image.image = y.clone();
    }
    {
      std::lock_guard<std::mutex> lock(mutex);
      cs.gaps.Add(image.sequence);
      if (!image.image.empty()) {
        if (side == 0) pairer.AddLeft(std::move(image));
        else pairer.AddRight(std::move(image));
      } else {
        ++stats.frames_skipped;
      }
    }
    ready.notify_all();
    request->reuse(libcamera::Request::ReuseBuffers);
    if (cs.started) cs.camera->queueRequest(request);
  }

  void Configure(int side, const std::string& id, const char* which) {
    CameraStream& cs = cams[side];
    cs.camera = manager->get(id);
    RB_CHECK(cs.camera != nullptr, "libcamera: no camera with id '", id, "' (", which, ")");
    RB_CHECK(cs.camera->acquire() == 0, "libcamera: camera '", id, "' is busy (", which, ")");
    cs.acquired = true;
    cs.config = cs.camera->generateConfiguration({libcamera::StreamRole::Viewfinder});
    RB_CHECK(cs.config && cs.config->size() == 1, "libcamera: camera '", id, "' gives no viewfinder stream");
    libcamera::StreamConfiguration& sc = cs.config->at(0);
    sc.size = libcamera::Size(static_cast<unsigned>(options.width), static_cast<unsigned>(options.height));
    sc.pixelFormat = libcamera::formats::YUV420;
    sc.bufferCount = static_cast<unsigned>(options.buffers);
    RB_CHECK(cs.config->validate() != libcamera::CameraConfiguration::Invalid, "libcamera: camera '", id,
             "' rejects every configuration near ", options.width, "x", options.height);
    const libcamera::PixelFormat pf = sc.pixelFormat;
    RB_CHECK(pf == libcamera::formats::YUV420 || pf == libcamera::formats::NV12 || pf == libcamera::formats::R8,
             "libcamera: camera '", id, "' offers ", pf.toString(), ", not R8/YUV420/NV12");
    RB_CHECK(cs.camera->configure(cs.config.get()) == 0, "libcamera: cannot configure camera '", id, "'");
    cs.stream = sc.stream();
    cs.width = static_cast<int>(sc.size.width);
    cs.height = static_cast<int>(sc.size.height);
    cs.stride = static_cast<int>(sc.stride);
    cs.format = StrCat(pf.toString(), " ", cs.width, "x", cs.height, " (", id, ")");
    cs.allocator = std::make_unique<libcamera::FrameBufferAllocator>(cs.camera);
    RB_CHECK(cs.allocator->allocate(cs.stream) >= 0, "libcamera: cannot allocate buffers for '", id, "'");
    for (const std::unique_ptr<libcamera::FrameBuffer>& fb : cs.allocator->buffers(cs.stream)) {
      const libcamera::FrameBuffer::Plane& plane = fb->planes()[0];
      void* p = mmap(nullptr, plane.offset + plane.length, PROT_READ, MAP_SHARED, plane.fd.get(), 0);
      RB_CHECK(p != MAP_FAILED, "libcamera: cannot map a buffer of '", id, "'");
      cs.mapped[fb.get()] = {p, plane.offset + plane.length, plane.offset};
      std::unique_ptr<libcamera::Request> request = cs.camera->createRequest();
      RB_CHECK(request && request->addBuffer(cs.stream, fb.get()) == 0, "libcamera: cannot create a request for '",
               id, "'");
      cs.requests.push_back(std::move(request));
    }
    if (side == 0) {
      cs.camera->requestCompleted.connect(this, &Impl::OnLeft);
    } else {
      cs.camera->requestCompleted.connect(this, &Impl::OnRight);
    }
  }
  void OnLeft(libcamera::Request* r) { OnRequestComplete(0, r); }
  void OnRight(libcamera::Request* r) { OnRequestComplete(1, r); }

  void Start() {
    for (CameraStream& cs : cams) {
      RB_CHECK(cs.camera->start() == 0, "libcamera: cannot start camera '", cs.camera->id(), "'");
      cs.started = true;
      for (auto& request : cs.requests) cs.camera->queueRequest(request.get());
    }
  }

  // Everything that holds a Camera (requests, allocator, configuration) goes before the manager stops: the
  // manager must not stop while a camera is still referenced.
  ~Impl() {
    for (CameraStream& cs : cams) {
      if (cs.started.exchange(false)) cs.camera->stop();
      if (cs.camera) cs.camera->requestCompleted.disconnect(this);
      cs.requests.clear();
      for (auto& entry : cs.mapped) munmap(entry.second.base, entry.second.length);
      cs.mapped.clear();
      if (cs.allocator && cs.stream != nullptr) cs.allocator->free(cs.stream);
      cs.allocator.reset();
      cs.config.reset();
      cs.stream = nullptr;
      if (cs.acquired) cs.camera->release();
      cs.acquired = false;
      cs.camera.reset();
    }
    if (manager) manager->stop();
  }
};

LibcameraStereoSource::LibcameraStereoSource(const LibcameraStereoOptions& options)
    : impl_(std::make_unique<Impl>(options)) {
  options.Check();
  QuietLibcameraLogs();
  impl_->manager = std::make_unique<libcamera::CameraManager>();
  RB_CHECK(impl_->manager->start() == 0, "libcamera: the camera manager did not start");
  const auto cameras = impl_->manager->cameras();
  RB_CHECK(cameras.size() >= 2 || (!options.left_camera.empty() && !options.right_camera.empty()),
           "libcamera: stereo needs two cameras, found ", cameras.size());
  const std::string left = options.left_camera.empty() ? cameras[0]->id() : options.left_camera;
  const std::string right = options.right_camera.empty() ? cameras[1]->id() : options.right_camera;
  RB_CHECK(left != right, "libcamera: left and right are the same camera '", left, "'");
  impl_->Configure(0, left, "left");
  impl_->Configure(1, right, "right");
  RB_CHECK(impl_->cams[0].width == impl_->cams[1].width && impl_->cams[0].height == impl_->cams[1].height,
           "libcamera: left gives ", impl_->cams[0].format, " but right gives ", impl_->cams[1].format);
  impl_->Start();
}

LibcameraStereoSource::~LibcameraStereoSource() = default;

FrameResult LibcameraStereoSource::Next() {
  FrameResult result;
  std::unique_lock<std::mutex> lock(impl_->mutex);
  std::optional<std::pair<TimedImage, TimedImage>> pair;
  const bool got = impl_->ready.wait_for(lock, std::chrono::milliseconds(impl_->options.timeout_ms), [&] {
    pair = impl_->pairer.Pop();
    return pair.has_value();
  });
  if (!got) {
    ++impl_->stats.timeouts;
    result.status = FrameStatus::kTimeout;
    result.reason = StrCat("no stereo pair within ", impl_->options.timeout_ms, " ms");
    return result;
  }
  result.frame = StereoFrameOf(std::move(*pair), impl_->next_index++);
  ++impl_->stats.frames_delivered;
  result.status = FrameStatus::kFrame;
  return result;
}

std::string LibcameraStereoSource::Describe() const {
  return StrCat("libcamera ", impl_->cams[0].format, " + ", impl_->cams[1].format);
}

FrameSourceStats LibcameraStereoSource::stats() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  FrameSourceStats s = impl_->stats;
  s.dropped_left = impl_->cams[0].gaps.dropped();
  s.dropped_right = impl_->cams[1].gaps.dropped();
  s.unpaired_left = impl_->pairer.unpaired_left();
  s.unpaired_right = impl_->pairer.unpaired_right();
  return s;
}

RecordingMeta LibcameraStereoSource::Meta() const {
  return {{"source", Describe()}, {"left_format", impl_->cams[0].format}, {"right_format", impl_->cams[1].format}};
}

}  // namespace rangebayes

#include "capture/tee_source.h"

namespace rangebayes {

FrameResult TeeSource::Next() {
  FrameResult r = inner_.Next();
  if (writer_ != nullptr && r.status == FrameStatus::kFrame) writer_->Write(r.frame);
  return r;
}

}  // namespace rangebayes

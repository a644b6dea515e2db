// SPDX-License-Identifier: Apache-2.0
// codec/src/training.h: what the prior-training tool
// (codec/tools/train_priors.cpp) needs of the encoder, and nothing else
// uses: an encoder whose models start flat, and its models at the end.
#ifndef PSQ_CODEC_TRAINING_H_
#define PSQ_CODEC_TRAINING_H_

#include "coding.h"
#include "psq/psq_codec.h"

namespace psq {
namespace codec {

struct TrainingAccess {
  // Makes `e`'s models start at p0 = 1/2, n = 0 (Models(false)) instead of
  // the priors of spec 6.2.7. Call before begin().
  static void use_flat_models(PsqEncoder& e);
  // The models' current state (after finish(): their final state).
  static const Models& models(const PsqEncoder& e);
};

}  // namespace codec
}  // namespace psq

#endif  // PSQ_CODEC_TRAINING_H_

// The composite of the methods with blend passes (method.h): how their final
// per-sample state becomes the image, per pixel, over the clear colour (the
// opaque background of a trace). One definition for every fidelity: the
// golden model and the cycle model resolve the same state with it.
//
//   +ac        A = 1 - mean_s T_s (total alpha),  R = samples the stochastic pass wrote,
//              C = A * (sum of their colours) / R  +  mean_s(T_s) * background
//   +depth     C = mean_s accum_s.rgb  +  (S - R) / S * background
//   +depth+ac  C = A * sum_s accum_s.rgb / sum_s accum_s.a  +  mean_s(T_s) * background
//   wboit      C = mean_s [ accum_s.rgb / clamp(accum_s.a) * (1 - T_s) + T_s * background ]
//   blend      the framebuffer (accum, RGBA) resolved in its encoding (framebuffer_image)
//
// T_s is the transmittance target (the product of 1 - alpha over the
// fragments at sample s), accum_s the accumulation target; a written sample
// is one whose depth is not the clear depth (docs/methods.md). The
// background is the clear colour, or, after a pre-pass of a frame's opaque
// and blended draws (PassKind::kPrepass), each sample's colour buffer:
// mean_s(T_s) * background is then mean_s(T_s * background_s), and +depth's
// (S - R) / S * background is mean_s (written_s ? 0 : background_s). Over a
// pre-pass the depth buffer no longer tells the written samples: +ac's
// stochastic pass writes (c, 1) into the accumulation target (written:
// accum_s.a != 0, its colour accum_s.rgb) and +depth's marks the
// transmittance target with 0 (written: T_s = 0; method.h,
// stochastic_colour_in_accum, stochastic_marks_transmittance).
#pragma once
#include <cstddef>

#include "rtl_models/functional/image.h"
#include "rtl_models/functional/method.h"
#include "rtl_models/functional/sample_store.h"

namespace ropsim {

/// The image of a method with blend passes from its final state; over each
/// sample's colour buffer when a pre-pass drew the background into it
/// (background_per_sample: every composite method on a frame with opaque or
/// blended draws). On a frame
/// whose target has an 8-bit encoding, each sample's composite (the
/// formula's term for sample s) is stored as the target stores it and the
/// pixel resolved as blend resolves its framebuffer, as light
/// (colour_buffer_image); on a float target the image is the formula's.
Image composite(const SampleStore& store, Method m, bool background_per_sample = false);

/// blend's image: each pixel's framebuffer samples resolved in the frame's
/// encoding (framebuffer_resolve_pixel, frame_encoding), as linear light. An
/// 8-bit target's resolved bytes are display code values, so the image holds
/// their sRGB decoding, which an sRGB PNG stores back as exactly those bytes
/// (the PNG of a unorm8 or srgb8 target is its bytes as stored); a float
/// target's values are the image's.
Image framebuffer_image(const SampleStore& store);

/// The image of a per-sample method's colour buffer on a frame whose target
/// has an 8-bit encoding e: each sample stored as the target stores it
/// (framebuffer_store of its working value), the pixel resolved as blend
/// resolves its framebuffer (framebuffer_resolve_pixel), as light; so equal
/// samples give blend's image bit for bit. The clear colour where untouched.
Image colour_buffer_image(const SampleStore& store, TargetEncoding e);

/// A method's image from its colour buffer's working values (the box filter
/// or the composite, framebuffer_blend.h) as the frame's target of encoding e
/// holds it: each value resolved into that encoding, then as light
/// (resolved_light), so that it compares with blend's image as screenshots
/// do. Nothing changes for a float target.
void encode_resolved(Image& img, TargetEncoding e);

}  // namespace ropsim

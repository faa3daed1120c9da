// The fixed-function module's names for its state's values (GL's enumerant
// names), shared by the subset's reasons (ff_state.cpp) and the generated
// programs' comments (ff_program.cpp). Private to the module.
#pragma once
#include "traces/glcapture/ff_program.h"

namespace ropsim::glcapture::ff_names {

inline const char* target_name(TexTarget t) {
  switch (t) {
    case TexTarget::k1D:
      return "GL_TEXTURE_1D";
    case TexTarget::k2D:
      return "GL_TEXTURE_2D";
    case TexTarget::k3D:
      return "GL_TEXTURE_3D";
    case TexTarget::kCubeMap:
      return "GL_TEXTURE_CUBE_MAP";
    case TexTarget::kRectangle:
      return "GL_TEXTURE_RECTANGLE";
    case TexTarget::kNone:
      break;
  }
  return "no texture target";
}

inline const char* base_name(TexBaseFormat b) {
  switch (b) {
    case TexBaseFormat::kAlpha:
      return "GL_ALPHA";
    case TexBaseFormat::kLuminance:
      return "GL_LUMINANCE";
    case TexBaseFormat::kLuminanceAlpha:
      return "GL_LUMINANCE_ALPHA";
    case TexBaseFormat::kIntensity:
      return "GL_INTENSITY";
    case TexBaseFormat::kRgb:
      return "GL_RGB";
    case TexBaseFormat::kRgba:
      return "GL_RGBA";
    case TexBaseFormat::kDepth:
      return "GL_DEPTH_COMPONENT";
  }
  return "?";
}

inline const char* combine_func_name(CombineFunc f) {
  switch (f) {
    case CombineFunc::kReplace:
      return "REPLACE";
    case CombineFunc::kModulate:
      return "MODULATE";
    case CombineFunc::kAdd:
      return "ADD";
    case CombineFunc::kAddSigned:
      return "ADD_SIGNED";
    case CombineFunc::kInterpolate:
      return "INTERPOLATE";
    case CombineFunc::kSubtract:
      return "SUBTRACT";
    case CombineFunc::kDot3Rgb:
      return "DOT3_RGB";
    case CombineFunc::kDot3Rgba:
      return "DOT3_RGBA";
    case CombineFunc::kOther:
      break;
  }
  return "?";
}

}  // namespace ropsim::glcapture::ff_names

// The real OpenGL, GLX and EGL entry points the capture library calls: never
// by name (the library exports those names: a call by name would come back to
// its own wrappers), always through this table, resolved with
// dlsym(RTLD_NEXT) and else the real glXGetProcAddressARB / eglGetProcAddress.
#pragma once
// clang-format off
#include <GL/gl.h>
#include <GL/glext.h>
#include <GL/glx.h>
#include <EGL/egl.h>
// clang-format on

namespace ropsim::glcapture {

// GLX and EGL entry points (not in glext.h's PFN list).
using PfnGlxSwapBuffers = void (*)(Display*, GLXDrawable);
using PfnGlxMakeCurrent = Bool (*)(Display*, GLXDrawable, GLXContext);
using PfnGlxMakeContextCurrent = Bool (*)(Display*, GLXDrawable, GLXDrawable, GLXContext);
using PfnGlxDestroyContext = void (*)(Display*, GLXContext);
using PfnGlxGetProcAddress = __GLXextFuncPtr (*)(const GLubyte*);
using PfnGlxGetCurrentContext = GLXContext (*)();
using PfnGlxGetCurrentDisplay = Display* (*)();
using PfnGlxGetCurrentDrawable = GLXDrawable (*)();
using PfnGlxQueryDrawable = void (*)(Display*, GLXDrawable, int, unsigned int*);
using PfnEglSwapBuffers = EGLBoolean (*)(EGLDisplay, EGLSurface);
using PfnEglMakeCurrent = EGLBoolean (*)(EGLDisplay, EGLSurface, EGLSurface, EGLContext);
using PfnEglDestroyContext = EGLBoolean (*)(EGLDisplay, EGLContext);
using PfnEglGetProcAddress = __eglMustCastToProperFunctionPointerType (*)(const char*);
using PfnEglGetCurrentContext = EGLContext (*)();
using PfnEglGetCurrentDisplay = EGLDisplay (*)();
using PfnEglGetCurrentSurface = EGLSurface (*)(EGLint);
using PfnEglQuerySurface = EGLBoolean (*)(EGLDisplay, EGLSurface, EGLint, EGLint*);
using PfnGlBegin = decltype(&::glBegin);
using PfnGlEnd = decltype(&::glEnd);

// GL 1.0 / 1.1 entry points have no PFN types in glext.h: decltype of
// gl.h's declarations (never called by name).
// X(type, name): the member `name` is the entry point "gl" #name (or the
// window-system one named in full).
#define ROPSIM_GL_ENTRY_POINTS(X)                                                                      \
  X(decltype(&::glDrawArrays), DrawArrays)                                                             \
  X(decltype(&::glDrawElements), DrawElements)                                                         \
  X(PFNGLDRAWARRAYSINSTANCEDPROC, DrawArraysInstanced)                                                 \
  X(PFNGLDRAWELEMENTSINSTANCEDPROC, DrawElementsInstanced)                                             \
  X(PFNGLDRAWELEMENTSBASEVERTEXPROC, DrawElementsBaseVertex)                                           \
  X(PFNGLDRAWELEMENTSINSTANCEDBASEVERTEXPROC, DrawElementsInstancedBaseVertex)                         \
  X(PFNGLDRAWRANGEELEMENTSPROC, DrawRangeElements)                                                     \
  X(PFNGLDRAWRANGEELEMENTSBASEVERTEXPROC, DrawRangeElementsBaseVertex)                                 \
  X(PFNGLDRAWARRAYSINSTANCEDBASEINSTANCEPROC, DrawArraysInstancedBaseInstance)                         \
  X(PFNGLDRAWELEMENTSINSTANCEDBASEINSTANCEPROC, DrawElementsInstancedBaseInstance)                     \
  X(PFNGLDRAWELEMENTSINSTANCEDBASEVERTEXBASEINSTANCEPROC, DrawElementsInstancedBaseVertexBaseInstance) \
  X(PFNGLMULTIDRAWARRAYSPROC, MultiDrawArrays)                                                         \
  X(PFNGLMULTIDRAWELEMENTSPROC, MultiDrawElements)                                                     \
  X(PFNGLMULTIDRAWELEMENTSBASEVERTEXPROC, MultiDrawElementsBaseVertex)                                 \
  X(PFNGLDRAWARRAYSINDIRECTPROC, DrawArraysIndirect)                                                   \
  X(PFNGLDRAWELEMENTSINDIRECTPROC, DrawElementsIndirect)                                               \
  X(PFNGLMULTIDRAWARRAYSINDIRECTPROC, MultiDrawArraysIndirect)                                         \
  X(PFNGLMULTIDRAWELEMENTSINDIRECTPROC, MultiDrawElementsIndirect)                                     \
  X(PfnGlBegin, Begin)                                                                                 \
  X(PfnGlEnd, End)                                                                                     \
  X(decltype(&::glCallList), CallList)                                                                 \
  X(decltype(&::glCallLists), CallLists)                                                               \
  X(decltype(&::glClear), Clear)                                                                       \
  X(PFNGLUSEPROGRAMPROC, UseProgram)                                                                   \
  X(PFNGLLINKPROGRAMPROC, LinkProgram)                                                                 \
  X(PFNGLDELETEPROGRAMPROC, DeleteProgram)                                                             \
  X(PFNGLBINDFRAMEBUFFERPROC, BindFramebuffer)                                                         \
  X(PFNGLOBJECTLABELPROC, ObjectLabel)                                                                 \
  X(decltype(&::glGetIntegerv), GetIntegerv)                                                           \
  X(decltype(&::glGetFloatv), GetFloatv)                                                               \
  X(decltype(&::glGetBooleanv), GetBooleanv)                                                           \
  X(PFNGLGETBOOLEANI_VPROC, GetBooleani_v)                                                             \
  X(PFNGLGETINTEGERI_VPROC, GetIntegeri_v)                                                             \
  X(PFNGLGETINTEGER64I_VPROC, GetInteger64i_v)                                                         \
  X(decltype(&::glIsEnabled), IsEnabled)                                                               \
  X(PFNGLISENABLEDIPROC, IsEnabledi)                                                                   \
  X(decltype(&::glEnable), Enable)                                                                     \
  X(decltype(&::glDisable), Disable)                                                                   \
  X(PFNGLENABLEIPROC, Enablei)                                                                         \
  X(PFNGLDISABLEIPROC, Disablei)                                                                       \
  X(decltype(&::glColorMask), ColorMask)                                                               \
  X(PFNGLCOLORMASKIPROC, ColorMaski)                                                                   \
  X(decltype(&::glReadPixels), ReadPixels)                                                             \
  X(decltype(&::glReadBuffer), ReadBuffer)                                                             \
  X(decltype(&::glPixelStorei), PixelStorei)                                                           \
  X(decltype(&::glFinish), Finish)                                                                     \
  X(decltype(&::glViewport), Viewport)                                                                 \
  X(PFNGLVIEWPORTINDEXEDFPROC, ViewportIndexedf)                                                       \
  X(decltype(&::glScissor), Scissor)                                                                   \
  X(decltype(&::glFrontFace), FrontFace)                                                               \
  X(PFNGLPROGRAMUNIFORM1IPROC, ProgramUniform1i)                                                       \
  X(decltype(&::glGetString), GetString)                                                               \
  X(decltype(&::glGetTexEnviv), GetTexEnviv)                                                           \
  X(decltype(&::glGetTexEnvfv), GetTexEnvfv)                                                           \
  X(decltype(&::glGetLightfv), GetLightfv)                                                             \
  X(decltype(&::glGetTexParameteriv), GetTexParameteriv)                                               \
  X(decltype(&::glGetTexLevelParameteriv), GetTexLevelParameteriv)                                     \
  X(PFNGLACTIVETEXTUREPROC, ActiveTexture)                                                             \
  X(PFNGLCREATEFRAMEBUFFERSPROC, CreateFramebuffers)                                                   \
  X(PFNGLNAMEDFRAMEBUFFERPARAMETERIPROC, NamedFramebufferParameteri)                                   \
  X(PFNGLCHECKNAMEDFRAMEBUFFERSTATUSPROC, CheckNamedFramebufferStatus)                                 \
  X(PFNGLGETFRAMEBUFFERATTACHMENTPARAMETERIVPROC, GetFramebufferAttachmentParameteriv)                 \
  X(PFNGLGETNAMEDFRAMEBUFFERATTACHMENTPARAMETERIVPROC, GetNamedFramebufferAttachmentParameteriv)       \
  X(PFNGLGETTEXTURELEVELPARAMETERIVPROC, GetTextureLevelParameteriv)                                   \
  X(PFNGLGETNAMEDRENDERBUFFERPARAMETERIVPROC, GetNamedRenderbufferParameteriv)                         \
  X(PFNGLCREATERENDERBUFFERSPROC, CreateRenderbuffers)                                                 \
  X(PFNGLNAMEDRENDERBUFFERSTORAGEMULTISAMPLEPROC, NamedRenderbufferStorageMultisample)                 \
  X(PFNGLNAMEDRENDERBUFFERSTORAGEPROC, NamedRenderbufferStorage)                                       \
  X(PFNGLNAMEDFRAMEBUFFERRENDERBUFFERPROC, NamedFramebufferRenderbuffer)                               \
  X(PFNGLBLITNAMEDFRAMEBUFFERPROC, BlitNamedFramebuffer)                                               \
  X(PFNGLCREATEBUFFERSPROC, CreateBuffers)                                                             \
  X(PFNGLNAMEDBUFFERDATAPROC, NamedBufferData)                                                         \
  X(PFNGLNAMEDBUFFERSUBDATAPROC, NamedBufferSubData)                                                   \
  X(PFNGLCLEARNAMEDBUFFERDATAPROC, ClearNamedBufferData)                                               \
  X(PFNGLGETNAMEDBUFFERSUBDATAPROC, GetNamedBufferSubData)                                             \
  X(PFNGLMAPNAMEDBUFFERRANGEPROC, MapNamedBufferRange)                                                 \
  X(PFNGLUNMAPNAMEDBUFFERPROC, UnmapNamedBuffer)                                                       \
  X(PFNGLBINDBUFFERPROC, BindBuffer)                                                                   \
  X(PFNGLBUFFERDATAPROC, BufferData)                                                                   \
  X(PFNGLGETSTRINGIPROC, GetStringi)                                                                   \
  X(PFNGLGETNAMEDBUFFERPARAMETERI64VPROC, GetNamedBufferParameteri64v)                                 \
  X(PFNGLBINDBUFFERBASEPROC, BindBufferBase)                                                           \
  X(PFNGLBINDBUFFERRANGEPROC, BindBufferRange)                                                         \
  X(PFNGLMEMORYBARRIERPROC, MemoryBarrier)                                                             \
  X(PFNGLCREATESHADERPROC, CreateShader)                                                               \
  X(PFNGLSHADERSOURCEPROC, ShaderSource)                                                               \
  X(PFNGLCOMPILESHADERPROC, CompileShader)                                                             \
  X(PFNGLGETSHADERIVPROC, GetShaderiv)                                                                 \
  X(PFNGLGETSHADERINFOLOGPROC, GetShaderInfoLog)                                                       \
  X(PFNGLGETSHADERSOURCEPROC, GetShaderSource)                                                         \
  X(PFNGLDELETESHADERPROC, DeleteShader)                                                               \
  X(PFNGLCREATEPROGRAMPROC, CreateProgram)                                                             \
  X(PFNGLATTACHSHADERPROC, AttachShader)                                                               \
  X(PFNGLGETPROGRAMIVPROC, GetProgramiv)                                                               \
  X(PFNGLGETPROGRAMINFOLOGPROC, GetProgramInfoLog)                                                     \
  X(PFNGLGETATTACHEDSHADERSPROC, GetAttachedShaders)                                                   \
  X(PFNGLGETACTIVEATTRIBPROC, GetActiveAttrib)                                                         \
  X(PFNGLGETATTRIBLOCATIONPROC, GetAttribLocation)                                                     \
  X(PFNGLBINDATTRIBLOCATIONPROC, BindAttribLocation)                                                   \
  X(PFNGLGETACTIVEUNIFORMPROC, GetActiveUniform)                                                       \
  X(PFNGLGETACTIVEUNIFORMSIVPROC, GetActiveUniformsiv)                                                 \
  X(PFNGLGETUNIFORMLOCATIONPROC, GetUniformLocation)                                                   \
  X(PFNGLGETUNIFORMFVPROC, GetUniformfv)                                                               \
  X(PFNGLGETUNIFORMIVPROC, GetUniformiv)                                                               \
  X(PFNGLGETUNIFORMUIVPROC, GetUniformuiv)                                                             \
  X(PFNGLGETUNIFORMDVPROC, GetUniformdv)                                                               \
  X(PFNGLPROGRAMUNIFORM1FVPROC, ProgramUniform1fv)                                                     \
  X(PFNGLPROGRAMUNIFORM2FVPROC, ProgramUniform2fv)                                                     \
  X(PFNGLPROGRAMUNIFORM3FVPROC, ProgramUniform3fv)                                                     \
  X(PFNGLPROGRAMUNIFORM4FVPROC, ProgramUniform4fv)                                                     \
  X(PFNGLPROGRAMUNIFORM1IVPROC, ProgramUniform1iv)                                                     \
  X(PFNGLPROGRAMUNIFORM2IVPROC, ProgramUniform2iv)                                                     \
  X(PFNGLPROGRAMUNIFORM3IVPROC, ProgramUniform3iv)                                                     \
  X(PFNGLPROGRAMUNIFORM4IVPROC, ProgramUniform4iv)                                                     \
  X(PFNGLPROGRAMUNIFORM1UIVPROC, ProgramUniform1uiv)                                                   \
  X(PFNGLPROGRAMUNIFORM2UIVPROC, ProgramUniform2uiv)                                                   \
  X(PFNGLPROGRAMUNIFORM3UIVPROC, ProgramUniform3uiv)                                                   \
  X(PFNGLPROGRAMUNIFORM4UIVPROC, ProgramUniform4uiv)                                                   \
  X(PFNGLPROGRAMUNIFORM1DVPROC, ProgramUniform1dv)                                                     \
  X(PFNGLPROGRAMUNIFORM2DVPROC, ProgramUniform2dv)                                                     \
  X(PFNGLPROGRAMUNIFORM3DVPROC, ProgramUniform3dv)                                                     \
  X(PFNGLPROGRAMUNIFORM4DVPROC, ProgramUniform4dv)                                                     \
  X(PFNGLPROGRAMUNIFORMMATRIX2FVPROC, ProgramUniformMatrix2fv)                                         \
  X(PFNGLPROGRAMUNIFORMMATRIX3FVPROC, ProgramUniformMatrix3fv)                                         \
  X(PFNGLPROGRAMUNIFORMMATRIX4FVPROC, ProgramUniformMatrix4fv)                                         \
  X(PFNGLPROGRAMUNIFORMMATRIX2X3FVPROC, ProgramUniformMatrix2x3fv)                                     \
  X(PFNGLPROGRAMUNIFORMMATRIX3X2FVPROC, ProgramUniformMatrix3x2fv)                                     \
  X(PFNGLPROGRAMUNIFORMMATRIX2X4FVPROC, ProgramUniformMatrix2x4fv)                                     \
  X(PFNGLPROGRAMUNIFORMMATRIX4X2FVPROC, ProgramUniformMatrix4x2fv)                                     \
  X(PFNGLPROGRAMUNIFORMMATRIX3X4FVPROC, ProgramUniformMatrix3x4fv)                                     \
  X(PFNGLPROGRAMUNIFORMMATRIX4X3FVPROC, ProgramUniformMatrix4x3fv)                                     \
  X(PFNGLPROGRAMUNIFORM2FPROC, ProgramUniform2f)                                                       \
  X(PFNGLPROGRAMUNIFORM1UIPROC, ProgramUniform1ui)                                                     \
  X(PFNGLGETACTIVEUNIFORMBLOCKIVPROC, GetActiveUniformBlockiv)                                         \
  X(PFNGLGETACTIVEUNIFORMBLOCKNAMEPROC, GetActiveUniformBlockName)                                     \
  X(PFNGLGETUNIFORMBLOCKINDEXPROC, GetUniformBlockIndex)                                               \
  X(PFNGLUNIFORMBLOCKBINDINGPROC, UniformBlockBinding)                                                 \
  X(PFNGLGETPROGRAMINTERFACEIVPROC, GetProgramInterfaceiv)                                             \
  X(PFNGLGETPROGRAMRESOURCEIVPROC, GetProgramResourceiv)                                               \
  X(PFNGLGETPROGRAMRESOURCENAMEPROC, GetProgramResourceName)                                           \
  X(PFNGLGETPROGRAMRESOURCEINDEXPROC, GetProgramResourceIndex)                                         \
  X(PFNGLSHADERSTORAGEBLOCKBINDINGPROC, ShaderStorageBlockBinding)                                     \
  X(PFNGLGETOBJECTLABELPROC, GetObjectLabel)                                                           \
  X(PFNGLGENQUERIESPROC, GenQueries)                                                                   \
  X(PFNGLBEGINQUERYPROC, BeginQuery)                                                                   \
  X(PFNGLENDQUERYPROC, EndQuery)                                                                       \
  X(PFNGLGETQUERYOBJECTUI64VPROC, GetQueryObjectui64v)                                                 \
  X(PFNGLGETQUERYIVPROC, GetQueryiv)                                                                   \
  X(PFNGLBEGINCONDITIONALRENDERPROC, BeginConditionalRender)                                           \
  X(PFNGLENDCONDITIONALRENDERPROC, EndConditionalRender)                                               \
  X(PFNGLSTENCILFUNCSEPARATEPROC, StencilFuncSeparate)                                                 \
  X(PFNGLSTENCILOPSEPARATEPROC, StencilOpSeparate)                                                     \
  X(PFNGLSTENCILMASKSEPARATEPROC, StencilMaskSeparate)                                                 \
  X(PFNGLCLEARNAMEDFRAMEBUFFERIVPROC, ClearNamedFramebufferiv)                                         \
  X(decltype(&::glDepthFunc), DepthFunc)                                                               \
  X(decltype(&::glDepthMask), DepthMask)                                                               \
  X(PFNGLCLEARNAMEDBUFFERSUBDATAPROC, ClearNamedBufferSubData)                                         \
  X(PFNGLCREATETEXTURESPROC, CreateTextures)                                                           \
  X(PFNGLTEXTUREBUFFERPROC, TextureBuffer)                                                             \
  X(decltype(&::glBindTexture), BindTexture)

#define ROPSIM_WS_ENTRY_POINTS(X)                    \
  X(PfnGlxSwapBuffers, glXSwapBuffers)               \
  X(PfnGlxMakeCurrent, glXMakeCurrent)               \
  X(PfnGlxMakeContextCurrent, glXMakeContextCurrent) \
  X(PfnGlxDestroyContext, glXDestroyContext)         \
  X(PfnGlxGetProcAddress, glXGetProcAddressARB)      \
  X(PfnGlxGetCurrentContext, glXGetCurrentContext)   \
  X(PfnGlxGetCurrentDisplay, glXGetCurrentDisplay)   \
  X(PfnGlxGetCurrentDrawable, glXGetCurrentDrawable) \
  X(PfnGlxQueryDrawable, glXQueryDrawable)           \
  X(PfnEglSwapBuffers, eglSwapBuffers)               \
  X(PfnEglMakeCurrent, eglMakeCurrent)               \
  X(PfnEglDestroyContext, eglDestroyContext)         \
  X(PfnEglGetProcAddress, eglGetProcAddress)         \
  X(PfnEglGetCurrentContext, eglGetCurrentContext)   \
  X(PfnEglGetCurrentDisplay, eglGetCurrentDisplay)   \
  X(PfnEglGetCurrentSurface, eglGetCurrentSurface)   \
  X(PfnEglQuerySurface, eglQuerySurface)

struct GlFunctions {
#define ROPSIM_MEMBER(type, name) type name = nullptr;
  ROPSIM_GL_ENTRY_POINTS(ROPSIM_MEMBER)
  ROPSIM_WS_ENTRY_POINTS(ROPSIM_MEMBER)
#undef ROPSIM_MEMBER
};

/// The real entry points, resolved on first use.
const GlFunctions& real_gl();
/// Whether the application's conditional rendering (glBeginConditionalRender) is on.
bool application_conditional_render();
/// The real entry point `name` (dlsym(RTLD_NEXT), else the real
/// glXGetProcAddressARB, else eglGetProcAddress), or nullptr.
void* real_proc_address(const char* name);

}  // namespace ropsim::glcapture

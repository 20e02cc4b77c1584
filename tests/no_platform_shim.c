/* no_platform_shim.c — preloaded into a child process (LD_PRELOAD) to make "no OpenCL platform"
 * whatever ICD loader and drivers the machine has: clGetPlatformIDs finds none, as the Khronos
 * loader reports it (CL_PLATFORM_NOT_FOUND_KHR, cl_khr_icd). Used by CliErrors.NoPlatform. */
#define CL_TARGET_OPENCL_VERSION 300
#include <CL/cl.h>
#include <CL/cl_ext.h>

CL_API_ENTRY cl_int CL_API_CALL clGetPlatformIDs(cl_uint num_entries, cl_platform_id* platforms,
                                                 cl_uint* num_platforms) {
  (void)num_entries;
  (void)platforms;
  if (num_platforms) *num_platforms = 0;
  return CL_PLATFORM_NOT_FOUND_KHR;
}

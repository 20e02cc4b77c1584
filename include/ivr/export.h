/* ivr/export.h — the one export macro: libivr hides every symbol that is not marked IVR_API. */
#ifndef IVR_EXPORT_H
#define IVR_EXPORT_H
#if defined(_WIN32)
#if defined(IVR_BUILDING_LIBRARY)
#define IVR_API __declspec(dllexport)
#else
#define IVR_API __declspec(dllimport)
#endif
#else
#define IVR_API __attribute__((visibility("default")))
#endif
#endif

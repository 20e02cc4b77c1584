// loss.cl — the image losses of docs/design.md per element: the term added to the loss and the
// derivative with respect to the pixel value.
#ifndef IVR_LOSS_CL
#define IVR_LOSS_CL
#include "config.cl"

#ifndef IVR_LOSS_L1  // 0: mean squared error, 1: mean absolute error
#define IVR_LOSS_L1 0
#endif

// dL/dpixel for one channel; *loss += its term. `norm` = 1 / (number of elements).
inline real loss_term(real value, real target, real norm, real* loss) {
  const real diff = value - target;
#if IVR_LOSS_L1
  *loss += fabs(diff) * norm;
  return diff > (real)0 ? norm : (diff < (real)0 ? -norm : (real)0);
#else
  *loss += diff * diff * norm;
  return (real)2 * diff * norm;
#endif
}

#endif

// loss.cl — the image losses of docs/design.md per element: the term added to the loss and the
// derivative with respect to the pixel value.
#ifndef IVR_LOSS_CL
#define IVR_LOSS_CL
#include "config.cl"

#ifndef IVR_LOSS_L1  // 0: mean squared error, 1: mean absolute error
#define IVR_LOSS_L1 0
#endif
#ifndef IVR_LOSS_DOT  // 1: sum of target * value, whose dL/dpixel is the target itself
#define IVR_LOSS_DOT 0
#endif

// dL/dpixel for one channel; *loss += its term. `norm` = 1 / (number of elements).
inline real loss_term(real value, real target, real norm, real* loss) {
#if IVR_LOSS_DOT
  // Not a mean: the target is dL/dimage as given (an autograd backward's weights), unscaled.
  (void)norm;
  *loss += value * target;
  return target;
#elif IVR_LOSS_L1
  const real diff = value - target;
  *loss += fabs(diff) * norm;
  return diff > (real)0 ? norm : (diff < (real)0 ? -norm : (real)0);
#else
  const real diff = value - target;
  *loss += diff * diff * norm;
  return (real)2 * diff * norm;
#endif
}

#endif

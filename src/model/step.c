#include "model/model_internal.h"
void mdl_step_free(sooc_model *m) { (void)m; }

; abbe export rrf-m556: axis skew compensation (config.g, or M500 with config-override.g)
M556 S100 X-0.003079 Y0.000356 Z0.000059

"""System identification: logged runs, parameters by MJCF name, the multiple-shooting fit with its uncertainty,
the fitted MJCF, and excitation signals."""

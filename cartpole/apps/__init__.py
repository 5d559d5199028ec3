"""What each command does, as functions a notebook can call: the LQR lab (:mod:`~cartpole.apps.lab`), the swing-up
(:mod:`~cartpole.apps.swingup`), feedforward beside feedback (:mod:`~cartpole.apps.feedforward`), robustness sweeps
(:mod:`~cartpole.apps.sweep`) and the benchmarks (:mod:`~cartpole.apps.bench`). The command line
(:mod:`cartpole.commands`) only parses arguments and prints what these return."""

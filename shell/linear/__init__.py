"""Linear systems and the signal blocks of flight software: the math that the linear-block models compile.

* :mod:`shell.linear.system`: :class:`~shell.linear.system.LinearSystem` (A, B, C, D, continuous or sampled,
  named signals) and its checks;
* :mod:`shell.linear.matrix_files`: state-space matrices from HDF5, MATLAB .mat and numpy .npz files, refused
  with file and key;
* :mod:`shell.linear.realization`: transfer function to a minimal realization, second-order filters (low-pass,
  notch, bending) and their Tustin discretization with prewarping, zero-order hold, series connection;
* :mod:`shell.linear.response`: frequency response and its derivative (Hessenberg form, compiled);
* :mod:`shell.linear.kernels`: the compiled per-step kernels: state-space derivative, output and update, delay
  line, saturation, dead zone, rate limiter.

Design-time work (realizations, discretizations, checks) is Python; what runs every step is in
:mod:`shell.linear.kernels`, over float64 arrays, allocation-free.
"""

"""Analysis on a built simulation: linearization, linear-model files, system modes from A.

``linearize`` (TM-2020-5008164 Sec. 7.1.3: central differences with Richardson extrapolation, step
sizes from a relative-error tolerance), ``linear_model_file`` (the HDF5 delivery layout of TM
App. G.4, python-control and MATLAB exports), ``system_modes`` (frequencies, damping and shapes from
A, compared with FE frequencies).
"""

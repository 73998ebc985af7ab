"""Named offsets of model kernels and the construction check that keeps them equal to the declarations.

``check_named_offsets`` (run by ``Model.__init__`` after ``configure``) must refuse a model whose
declarations no longer match the offsets its kernels were compiled with: a subclass that reorders,
resizes, adds or removes a declaration, or a configure that reorders a shape-dependent declaration.
The refusals must name the model, the declaration and both offsets. Changing only a default is fine.
"""

from dataclasses import replace

import numpy as np
import pytest
from numba.core.caching import NullCache
from numba.core.registry import CPUDispatcher

from shell.model import Declarations, InputPort, Layout, Model, ModelError, Parameter, State, named_offsets
from shell.models.allocation import NodeLoadSum
from shell.models.controllers import LqrStateFeedback
from shell.models.imu import Imu
from shell.models.pd_attitude import PdAttitudeController
from shell.models.thruster import Thruster
from shell.models.user_hook import UserFunction
from tests.models.model_cases import cases


def test_named_offsets_are_the_packed_start_offsets():
    declarations = (Parameter("a", shape=(3,)), Parameter("b", shape=(2, 2)), Parameter("c"), Parameter("d", shape=5))
    offsets = named_offsets(declarations)
    layout = Layout.of(declarations)  # independent: the simulation's own packing
    assert offsets._fields == ("a", "b", "c", "d")
    assert tuple(offsets) == (0, 3, 7, 8) == tuple(layout.offsets[n] for n in "abcd")


def test_a_subclass_that_reorders_a_declaration_tuple_is_refused():
    class Reordered(PdAttitudeController):
        parameters = PdAttitudeController.parameters[::-1]

    with pytest.raises(ModelError) as refused:
        Reordered("pd")
    message = str(refused.value)
    # angular_velocity_command (3) now comes first: kp sits behind 3 + 4 + 3 values
    assert "model pd: Reordered: parameter 'kp' is at offset 10 of the declarations" in message
    assert "its kernels read it at offset 0" in message


def test_a_subclass_that_resizes_or_adds_a_declaration_is_refused():
    kp, *rest = PdAttitudeController.parameters

    class Resized(PdAttitudeController):
        parameters = (replace(kp, default=(1.0, 1.0, 1.0, 1.0), shape=(4,)), *rest)

    with pytest.raises(ModelError, match=r"model pd: Resized: parameter 'kd' is at offset 4 .* offset 3"):
        Resized("pd")

    class Extended(PdAttitudeController):
        discrete_states = PdAttitudeController.discrete_states + (State("extra", "", (), 0.0),)

    with pytest.raises(ModelError, match=r"model pd: Extended: discrete_states .*not declared: \[\], not read: "
                                         r"\['extra'\]"):
        Extended("pd")


def test_a_subclass_that_changes_only_defaults_is_accepted():
    kp, *rest = PdAttitudeController.parameters

    class Stiffer(PdAttitudeController):
        parameters = (replace(kp, default=(5.0, 6.0, 7.0)), *rest)

    assert np.array_equal(Stiffer("pd").parameter("kp"), [5.0, 6.0, 7.0])


def test_a_reordered_shape_dependent_layout_is_refused(tmp_path):
    # LQR offsets past the gain are derived in the kernel (None), but the order is still checked
    np.save(tmp_path / "k.npy", np.ones((2, 3)))

    class Swapped(LqrStateFeedback):
        def declare(self):
            super().declare()
            self.parameters = self.parameters[::-1]

    with pytest.raises(ModelError) as refused:
        Swapped("lqr", gain_file=str(tmp_path / "k.npy"))
    assert "model lqr: Swapped: parameter 'gain' is at offset 3 of the declarations but its kernels read it at " \
           "offset 0" in str(refused.value)

    class Interleaved(NodeLoadSum):
        def declare(self):
            super().declare()
            self.inputs = tuple(sorted(self.inputs, key=lambda d: d.name))  # force_0, force_1, torque_0, ...

    with pytest.raises(ModelError, match=r"model loads: Interleaved: input 'torque_0' is at offset 6 .* offset 0"):
        Interleaved("loads", count=2)


def test_user_function_outputs_and_held_states_must_share_one_layout():
    class Shuffled(UserFunction):
        def declare(self):
            super().declare()
            self.discrete_states = self.discrete_states[::-1]

    with pytest.raises(ModelError, match=r"model hook: Shuffled: discrete state 'b' is at offset 1 .* offset 0"):
        Shuffled("hook", function="tests.models.model_cases:hold_inputs", inputs={"a": {"shape": [3]}},
                 outputs={"b": {}, "c": {}}, period=0.1)


def test_an_unknown_offsets_key_is_refused():
    class Misnamed(PdAttitudeController):
        offsets = {**PdAttitudeController.offsets, "q": named_offsets(PdAttitudeController.parameters)}

    with pytest.raises(ModelError, match=r"model pd: Misnamed: offsets key 'q': expected one of"):
        Misnamed("pd")


def test_configuration_dependent_initial_values_keep_the_checked_layout():
    # the period and mode set in configure only change initial values, so the checks pass
    imu = Imu("imu", period=0.02, latency=0.04)
    assert imu.z_layout.shapes["records"] == (3 * 18,)
    jet = Thruster("jet", mode="on_off", max_thrust=1.0, isp=100.0, period=0.5)
    assert np.array_equal(jet.initial_discrete_state()[jet.z_layout.slice("cycle")], [1.0, 0.5])


def test_every_kernel_is_compiled_unless_the_model_says_its_update_is_python(tmp_path):
    python_updates = set()
    for case, module, class_name, kwargs in cases(tmp_path):
        m = getattr(__import__(f"shell.models.{module}", fromlist=[class_name]), class_name)(case, **kwargs)
        for kernel in ("state_outputs", "feedthrough_outputs", "derivatives", "zero_crossing_values", "update"):
            fn = getattr(m, kernel)
            if fn is None or (kernel == "update" and m.python_update):
                continue
            assert isinstance(fn, CPUDispatcher), f"{class_name}.{kernel} is not numba-compiled"
            # numba keeps no public flag for cache=True; a dispatcher without it has a NullCache
            assert not isinstance(fn._cache, NullCache), f"{class_name}.{kernel} is not cached on disk"
        if m.python_update:
            assert m.update is not None and not isinstance(m.update, CPUDispatcher)
            python_updates.add(class_name)
    # the three that must stay Python: user code, scipy's linear program, the engine's Python API
    assert python_updates == {"UserFunction", "NonnegativeAllocator", "MassDepletion"}


def test_declarations_give_the_offsets_and_the_class_attributes():
    declarations = Declarations(parameters=(Parameter("a", shape=(3,)), Parameter("b")),
                                inputs=(InputPort("u", shape=(2,)), InputPort("v"), InputPort("w")), sized=("u",))
    assert tuple(declarations.P) == (0, 3) and declarations.P._fields == ("a", "b")
    assert tuple(declarations.U) == (0, None, None)  # after a configuration-sized input the kernel derives them

    class Plain(Model):
        declarations = Declarations(parameters=(Parameter("a", shape=(3,), default=0.0), Parameter("b", default=1.0)))

    assert Plain.parameters == Plain.declarations.parameters and Plain.offsets["p"] == (0, 3)
    assert Plain("plain").p_layout.offsets == {"a": 0, "b": 3}
    wider = declarations.replace(u={"shape": (5,), "unit": "m"})
    assert [d.name for d in wider.inputs] == ["u", "v", "w"] and wider.inputs[0].shape == (5,)
    assert wider.inputs[0].unit == "m" and wider.U == declarations.U
    with pytest.raises(ModelError, match=r"u has no field\(s\) \['initial'\]"):
        declarations.replace(u={"initial": 1.0})
    with pytest.raises(ModelError, match=r"no declarations named \['x'\]"):
        declarations.replace(x={"shape": (2,)})
    with pytest.raises(ModelError, match=r"sized names \['x'\] are not declared"):
        Declarations(inputs=(InputPort("u"),), sized=("x",))

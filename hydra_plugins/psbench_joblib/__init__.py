"""psbench's ``-m`` launcher as a Hydra plugin (Hydra instantiates launchers only from
``hydra_plugins`` modules); the code is :mod:`psbench.harness.launcher`."""
from psbench.harness.launcher import ResilientJoblibLauncher as _Base


class ResilientJoblibLauncher(_Base):
    """:class:`psbench.harness.launcher.ResilientJoblibLauncher`."""

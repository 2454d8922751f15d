"""The GA workers, one process per behaviour, on Eclipse Zenoh: the worker (:mod:`.worker`), its
partner models (:mod:`.models`), pacing (:mod:`.pacing`), checkpoints (:mod:`.checkpoint`) and the
recorded-history feed of the offline regime (:mod:`.history`)."""

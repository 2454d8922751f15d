"""The dynamics of a finished run: each published version of a behaviour played against each of its partner's
(Cliff & Miller's CIAO matrix) and against all of them (Floreano & Nolfi's master tournament), for any task.

``matrix`` plays them; ``command`` is ``coevo dynamics`` and draws them.  Nothing is imported here.
"""

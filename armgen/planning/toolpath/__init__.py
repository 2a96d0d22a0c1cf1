"""The tool paths of the resolved-rate planners: the circle and the line with their rest-to-rest
time laws (:mod:`.paths`, fixed duration), and programs: sequences of straight, circular and
sampled moves with rounded corners
(:mod:`.geometry`), driven at a tool speed by a time law along the path length
(:mod:`.timelaw`), read from a task file's ``[path] type = "program"`` (:mod:`.task`) and kept
within the joints' speed limits (:mod:`.limits`). The geometry and the time law are pure
NumPy/SciPy on SI values: the planners use them, and so can a firmware generator."""

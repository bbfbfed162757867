"""The root control laws (robotgen.model.laws.registry: those with ``root`` set), one module or
package each: laws that are the root of their spec and make the module's functions themselves
(robotgen.symbolic.root_laws.law.RootLaw). They build on the tree's graphs
(robotgen.symbolic.system_kernels, robotgen.symbolic.plant); the tree laws below them
(robotgen.symbolic.control) import nothing from here."""

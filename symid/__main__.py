from symid.cli import main

raise SystemExit(main())

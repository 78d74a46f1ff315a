from psvs.cli.main import main

raise SystemExit(main())

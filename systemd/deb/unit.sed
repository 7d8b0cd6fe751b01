# sed script: systemd/plcd.service as the Debian package installs it, its paths under /usr.
# systemd/deb/build applies it; tests/deb_package.rs checks the result.
1i\
# This copy: installed by the Debian package plcd as /usr/lib/systemd/system/plcd.service, made\
# from systemd/plcd.service with its paths under /usr. Its example drop-ins are in\
# /usr/share/plcd/drop-ins/ (docs/DEPLOY.md, "Installing the Debian package").\
#
s#/usr/local/bin/plcd#/usr/bin/plcd#g
s#/usr/local/share/doc/plcd#/usr/share/doc/plcd#g
